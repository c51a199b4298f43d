//! The deployment files: every Kubernetes manifest parsed and checked for what a cluster would
//! reject or silently get wrong (kinds, selectors, ports, Secret keys, the KEDA target and metric);
//! the compose file's wiring; the shell scripts' syntax; and the Slurm worker script run for real
//! against a coordinator on loopback.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

use serde_json::Value;

use crate::common::*;

/// A parsed YAML document and the file it came from.
#[derive(Debug, Clone)]
struct Doc {
    file: String,
    value: Value,
}

impl Doc {
    fn kind(&self) -> &str {
        self.value["kind"].as_str().unwrap_or_default()
    }

    fn name(&self) -> &str {
        self.value["metadata"]["name"].as_str().unwrap_or_default()
    }

    fn label(&self) -> String {
        format!("{}: {} {}", self.file, self.kind(), self.name())
    }
}

/// Every document of a YAML file, as JSON values.
fn parse_yaml(path: &Path) -> Vec<Value> {
    use serde::Deserialize as _;
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_norway::Deserializer::from_str(&text)
        .map(|d| Value::deserialize(d).unwrap_or_else(|e| panic!("{}: not valid YAML: {e}", path.display())))
        .filter(|v| !v.is_null())
        .collect()
}

fn manifests() -> Vec<Doc> {
    let dir = workspace().join("deploy/kubernetes");
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|e| e.expect("dir entry").path())
        .filter(|p| p.extension().is_some_and(|x| x == "yaml" || x == "yml"))
        .collect();
    files.sort();
    assert!(!files.is_empty(), "no manifests in {}", dir.display());
    files
        .iter()
        .flat_map(|f| {
            let name = f.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
            parse_yaml(f).into_iter().map(move |value| Doc { file: name.clone(), value })
        })
        .collect()
}

fn is_dns_label(s: &str) -> bool {
    !s.is_empty()
        && s.len() <= 63
        && s.bytes().all(|b| b.is_ascii_lowercase() || b.is_ascii_digit() || b == b'-')
        && !s.starts_with('-')
        && !s.ends_with('-')
}

fn labels(v: &Value) -> BTreeMap<String, String> {
    v.as_object()
        .map(|m| m.iter().map(|(k, v)| (k.clone(), v.as_str().unwrap_or_default().to_string())).collect())
        .unwrap_or_default()
}

/// `sub` ⊆ `labels`, and `sub` not empty.
fn selects(sub: &BTreeMap<String, String>, labels: &BTreeMap<String, String>) -> bool {
    !sub.is_empty() && sub.iter().all(|(k, v)| labels.get(k) == Some(v))
}

fn port_in_range(v: &Value) -> bool {
    v.as_i64().is_some_and(|p| (1..=65535).contains(&p))
}

/// A container port named or numbered `p`.
fn container_has_port(container: &Value, p: &Value) -> bool {
    let ports = container["ports"].as_array().cloned().unwrap_or_default();
    ports.iter().any(|cp| match p {
        Value::String(name) => cp["name"].as_str() == Some(name.as_str()),
        Value::Number(_) => cp["containerPort"] == *p,
        _ => false,
    })
}

/// The workloads' pod templates: (doc, template).
fn workloads(docs: &[Doc]) -> Vec<(&Doc, &Value)> {
    docs.iter()
        .filter(|d| matches!(d.kind(), "Deployment" | "StatefulSet"))
        .map(|d| (d, &d.value["spec"]["template"]))
        .collect()
}

/// The value after `flag` in an argument list.
fn arg_after<'a>(args: &'a [Value], flag: &str) -> Option<&'a str> {
    args.iter().position(|a| a.as_str() == Some(flag)).and_then(|i| args.get(i + 1)).and_then(Value::as_str)
}

#[test]
fn kubernetes_manifests_are_consistent() {
    let docs = manifests();
    let known: BTreeSet<(&str, &str)> = [
        ("v1", "Service"),
        ("v1", "Secret"),
        ("apps/v1", "StatefulSet"),
        ("apps/v1", "Deployment"),
        ("keda.sh/v1alpha1", "ScaledObject"),
    ]
    .into_iter()
    .collect();
    let mut seen = BTreeSet::new();
    for d in &docs {
        let api = d.value["apiVersion"].as_str().unwrap_or_default();
        assert!(known.contains(&(api, d.kind())), "{}: unknown apiVersion/kind {api}/{}", d.file, d.kind());
        assert!(is_dns_label(d.name()), "{}: metadata.name `{}` is not a DNS label", d.label(), d.name());
        assert!(seen.insert((d.kind().to_string(), d.name().to_string())), "{}: defined twice", d.label());
    }
    for kind in ["Service", "Secret", "StatefulSet", "Deployment", "ScaledObject"] {
        assert!(docs.iter().any(|d| d.kind() == kind), "no {kind} among the manifests");
    }

    let secrets: BTreeMap<&str, BTreeSet<String>> = docs
        .iter()
        .filter(|d| d.kind() == "Secret")
        .map(|d| {
            let mut keys = BTreeSet::new();
            for field in ["data", "stringData"] {
                if let Some(m) = d.value[field].as_object() {
                    keys.extend(m.keys().cloned());
                }
            }
            (d.name(), keys)
        })
        .collect();

    for (d, template) in workloads(&docs) {
        let spec = &d.value["spec"];
        let selector = labels(&spec["selector"]["matchLabels"]);
        let pod_labels = labels(&template["metadata"]["labels"]);
        assert!(
            selects(&selector, &pod_labels),
            "{}: selector {selector:?} does not match the template's labels {pod_labels:?}",
            d.label()
        );
        let pod = &template["spec"];
        let containers = pod["containers"].as_array().unwrap_or_else(|| panic!("{}: no containers", d.label()));
        assert!(!containers.is_empty(), "{}: no containers", d.label());
        let mut volumes: BTreeSet<String> = pod["volumes"]
            .as_array()
            .into_iter()
            .flatten()
            .filter_map(|v| v["name"].as_str().map(String::from))
            .collect();
        if d.kind() == "StatefulSet" {
            let service = spec["serviceName"].as_str().unwrap_or_default();
            assert!(
                docs.iter().any(|s| s.kind() == "Service" && s.name() == service),
                "{}: serviceName `{service}` is not a Service here",
                d.label()
            );
            assert_eq!(spec["replicas"], 1, "{}: the coordinator's SQLite file allows one replica", d.label());
            for t in spec["volumeClaimTemplates"].as_array().into_iter().flatten() {
                volumes.insert(t["metadata"]["name"].as_str().unwrap_or_default().to_string());
                assert!(
                    t["spec"]["resources"]["requests"]["storage"].is_string(),
                    "{}: claim without a size",
                    d.label()
                );
            }
        }
        for c in containers {
            let cname = c["name"].as_str().unwrap_or_default();
            let at = format!("{} container {cname}", d.label());
            assert!(is_dns_label(cname), "{at}: bad name");
            assert!(c["image"].as_str().is_some_and(|i| !i.is_empty()), "{at}: no image");
            for p in c["ports"].as_array().into_iter().flatten() {
                assert!(port_in_range(&p["containerPort"]), "{at}: containerPort {}", p["containerPort"]);
                if let Some(n) = p["name"].as_str() {
                    assert!(n.len() <= 15 && is_dns_label(n), "{at}: port name `{n}` (at most 15 characters)");
                }
            }
            for probe in ["readinessProbe", "livenessProbe", "startupProbe"] {
                let get = &c[probe]["httpGet"];
                if get.is_null() {
                    continue;
                }
                assert!(container_has_port(c, &get["port"]), "{at}: {probe} port {} is no container port", get["port"]);
                assert_eq!(get["path"], "/healthz", "{at}: {probe} should ask /healthz");
            }
            for m in c["volumeMounts"].as_array().into_iter().flatten() {
                let v = m["name"].as_str().unwrap_or_default();
                assert!(volumes.contains(v), "{at}: mounts `{v}`, which is no volume of the pod");
            }
            for e in c["env"].as_array().into_iter().flatten() {
                let r = &e["valueFrom"]["secretKeyRef"];
                if r.is_null() {
                    continue;
                }
                let (s, k) = (r["name"].as_str().unwrap_or_default(), r["key"].as_str().unwrap_or_default());
                let keys =
                    secrets.get(s).unwrap_or_else(|| panic!("{at}: env {} reads Secret `{s}`, not defined", e["name"]));
                assert!(
                    keys.contains(k),
                    "{at}: env {} reads key `{k}` of Secret `{s}`, which has {keys:?}",
                    e["name"]
                );
            }
            let requests = &c["resources"]["requests"];
            assert!(requests["cpu"].is_string() && requests["memory"].is_string(), "{at}: no CPU and memory requests");
        }
    }

    // Services select a workload's pods and point at one of their ports
    for s in docs.iter().filter(|d| d.kind() == "Service") {
        let selector = labels(&s.value["spec"]["selector"]);
        let targets: Vec<_> = workloads(&docs)
            .into_iter()
            .filter(|(_, t)| selects(&selector, &labels(&t["metadata"]["labels"])))
            .collect();
        assert!(!targets.is_empty(), "{}: selector {selector:?} selects no workload", s.label());
        for p in s.value["spec"]["ports"].as_array().into_iter().flatten() {
            assert!(port_in_range(&p["port"]), "{}: port {}", s.label(), p["port"]);
            let target = if p["targetPort"].is_null() { &p["port"] } else { &p["targetPort"] };
            for (w, t) in &targets {
                let ok =
                    t["spec"]["containers"].as_array().into_iter().flatten().any(|c| container_has_port(c, target));
                assert!(ok, "{}: targetPort {target} is no container port of {}", s.label(), w.label());
            }
        }
    }

    // the coordinator: a StatefulSet whose Service the workers are pointed at
    let coord_service = docs.iter().find(|d| d.kind() == "Service").expect("a Service");
    let service_port = coord_service.value["spec"]["ports"][0]["port"].as_i64().expect("service port");
    let worker = docs.iter().find(|d| d.kind() == "Deployment").expect("the worker Deployment");
    let wc = &worker.value["spec"]["template"]["spec"]["containers"][0];
    let args = wc["args"].as_array().cloned().unwrap_or_default();
    assert_eq!(args.first().and_then(Value::as_str), Some("work"), "{}: should run `cryofit work`", worker.label());
    let url = arg_after(&args, "--coordinator").unwrap_or_else(|| panic!("{}: no --coordinator", worker.label()));
    assert_eq!(url, format!("http://{}:{service_port}", coord_service.name()), "{}: --coordinator", worker.label());
    let slots = arg_after(&args, "--slots").unwrap_or_else(|| panic!("{}: no --slots", worker.label()));
    assert_eq!(
        Some(slots),
        wc["resources"]["requests"]["cpu"].as_str(),
        "{}: --slots should equal the CPU request",
        worker.label()
    );
    let coord = docs.iter().find(|d| d.kind() == "StatefulSet").expect("the coordinator StatefulSet");
    let cc = &coord.value["spec"]["template"]["spec"]["containers"][0];
    assert_eq!(cc["args"][0], "serve", "{}: should run `cryofit serve`", coord.label());
    for probe in ["readinessProbe", "livenessProbe"] {
        assert!(!cc[probe]["httpGet"].is_null(), "{}: no {probe}", coord.label());
    }
    let env: BTreeSet<&str> = cc["env"].as_array().into_iter().flatten().filter_map(|e| e["name"].as_str()).collect();
    assert!(
        env.contains("CRYOFIT_CLIENT_TOKEN") && env.contains("CRYOFIT_WORKER_TOKEN"),
        "{}: the coordinator needs both tokens (it refuses a non-loopback address without them)",
        coord.label()
    );

    // KEDA scales the worker Deployment on a metric the coordinator really exposes
    let so = docs.iter().find(|d| d.kind() == "ScaledObject").expect("a ScaledObject");
    let target = &so.value["spec"]["scaleTargetRef"];
    assert_eq!(target["name"].as_str(), Some(worker.name()), "{}: scaleTargetRef", so.label());
    assert!(target["kind"].is_null() || target["kind"] == "Deployment", "{}: scaleTargetRef kind", so.label());
    let triggers = so.value["spec"]["triggers"].as_array().cloned().unwrap_or_default();
    let prom = triggers
        .iter()
        .find(|t| t["type"] == "prometheus")
        .unwrap_or_else(|| panic!("{}: no prometheus trigger", so.label()));
    let query = prom["metadata"]["query"].as_str().unwrap_or_default();
    assert!(query.contains("cryofit_queue_depth"), "{}: the query should use cryofit_queue_depth: {query}", so.label());
    assert!(
        prom["metadata"]["serverAddress"].as_str().is_some_and(|a| a.starts_with("http")),
        "{}: serverAddress",
        so.label()
    );
    assert!(
        prom["metadata"]["threshold"].as_str().and_then(|t| t.parse::<f64>().ok()).is_some_and(|t| t > 0.0),
        "{}: threshold must be a positive number in a string",
        so.label()
    );
    let exposed = live_metric_names();
    for name in metric_names(query) {
        assert!(
            exposed.contains(&name),
            "{}: the query uses `{name}`, which /metrics does not expose: {exposed:?}",
            so.label()
        );
    }
}

/// The `cryofit_…` names in a PromQL query.
fn metric_names(query: &str) -> BTreeSet<String> {
    let mut out = BTreeSet::new();
    let mut rest = query;
    while let Some(i) = rest.find("cryofit_") {
        let tail = &rest[i..];
        let end = tail.find(|c: char| !(c.is_ascii_alphanumeric() || c == '_')).unwrap_or(tail.len());
        out.insert(tail[..end].to_string());
        rest = &tail[end..];
    }
    out
}

/// The metric names a real coordinator's `/metrics` declares (`# TYPE name …`).
fn live_metric_names() -> BTreeSet<String> {
    let dir = scratch("metrics");
    let server = Server::start(&dir, "serve", "127.0.0.1:0", &dir.join("c.db"), &[]);
    let text = http().get(format!("{}/metrics", server.url)).send().expect("GET /metrics").text().expect("body");
    text.lines()
        .filter_map(|l| l.strip_prefix("# TYPE "))
        .filter_map(|l| l.split_whitespace().next())
        .map(String::from)
        .collect()
}

#[test]
fn compose_file_wires_workers_to_a_healthy_coordinator() {
    let path = workspace().join("docker/compose.yaml");
    let docs = parse_yaml(&path);
    assert_eq!(docs.len(), 1, "compose.yaml: one document");
    let c = &docs[0];
    let coord = &c["services"]["coordinator"];
    let worker = &c["services"]["worker"];
    assert!(coord.is_object() && worker.is_object(), "compose.yaml: services coordinator and worker");
    let test = coord["healthcheck"]["test"].as_array().cloned().unwrap_or_default();
    assert!(
        test.iter().any(|a| a == "healthcheck"),
        "coordinator healthcheck should run `cryofit healthcheck`: {test:?}"
    );
    assert_eq!(
        worker["depends_on"]["coordinator"]["condition"], "service_healthy",
        "workers wait for a healthy coordinator"
    );
    assert_eq!(worker["healthcheck"]["disable"], true, "a worker serves no /healthz");
    // the volume holds the database
    let db = arg_after(coord["command"].as_array().map_or(&[][..], Vec::as_slice), "--database").expect("--database");
    let mounts: Vec<&str> = coord["volumes"].as_array().into_iter().flatten().filter_map(Value::as_str).collect();
    let (volume, mount) = mounts.iter().find_map(|m| m.split_once(':')).expect("a volume mount");
    assert!(db.starts_with(mount.trim_end_matches(":rw")), "--database {db} is not on the volume mounted at {mount}");
    assert!(c["volumes"].get(volume).is_some(), "volume `{volume}` is not declared");
    // workers reach the coordinator by its service name and container port
    let cmd = worker["command"].as_array().cloned().unwrap_or_default();
    assert_eq!(arg_after(&cmd, "--coordinator"), Some("http://coordinator:8700"));
    let bind = arg_after(coord["command"].as_array().map_or(&[][..], Vec::as_slice), "--bind").expect("--bind");
    assert_eq!(bind, "0.0.0.0:8700");
    let ports: Vec<&str> = coord["ports"].as_array().into_iter().flatten().filter_map(Value::as_str).collect();
    assert!(ports.iter().any(|p| p.ends_with(":8700")), "the coordinator's port 8700 is published: {ports:?}");
    // tokens come from the environment (env file), never from the compose file itself
    assert!(coord["environment"]["CRYOFIT_CLIENT_TOKEN"].as_str().is_some_and(|v| v.starts_with("${")));
    assert!(coord["environment"]["CRYOFIT_WORKER_TOKEN"].as_str().is_some_and(|v| v.starts_with("${")));
    assert!(worker["environment"]["CRYOFIT_TOKEN"].as_str().is_some_and(|v| v.starts_with("${CRYOFIT_WORKER_TOKEN")));

    // and Compose itself accepts it, where Compose v2 is installed
    match Command::new("docker").args(["compose", "version"]).output() {
        Ok(o) if o.status.success() => {
            let out = Command::new("docker")
                .args(["compose", "-f", &path.display().to_string(), "config", "-q"])
                .env_remove("CRYOFIT_CLIENT_TOKEN")
                .env_remove("CRYOFIT_WORKER_TOKEN")
                .output()
                .expect("run docker compose config");
            assert!(out.status.success(), "docker compose config -q: {}", String::from_utf8_lossy(&out.stderr));
        }
        _ => eprintln!(
            "skipped `docker compose config -q`: docker compose (v2) is not installed (docker/setup.sh installs it)"
        ),
    }
}

#[test]
fn shell_scripts_parse() {
    let root = workspace();
    for script in [
        "deploy/slurm/workers.sbatch",
        "deploy/slurm/coordinator.sbatch",
        "docker/test.sh",
        "docker/build-image.sh",
        "docker/setup.sh",
    ] {
        let path = root.join(script);
        let out = Command::new("bash").arg("-n").arg(&path).output().expect("run bash -n");
        assert!(out.status.success(), "bash -n {script}: {}", String::from_utf8_lossy(&out.stderr));
        let text = std::fs::read_to_string(&path).expect("read script");
        assert!(text.starts_with("#!/usr/bin/env bash"), "{script}: no bash shebang");
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt as _;
            let mode = std::fs::metadata(&path).expect("metadata").permissions().mode();
            assert!(mode & 0o111 != 0, "{script} is not executable");
        }
    }
}

/// Runs `bash deploy/slurm/workers.sbatch` with `env`, outside Slurm.
fn run_sbatch(dir: &Path, env: &[(&str, String)]) -> (std::process::ExitStatus, String) {
    let bin = cryofit_bin();
    let bin_dir = bin.parent().expect("binary folder");
    let log = dir.join("sbatch.log");
    let mut cmd = Command::new("bash");
    cmd.arg(workspace().join("deploy/slurm/workers.sbatch"))
        .current_dir(dir)
        .env_remove("CRYOFIT_COORDINATOR")
        .env_remove("CRYOFIT_TOKEN")
        .env("HOME", dir)
        .env("PATH", format!("{}:{}", bin_dir.display(), std::env::var("PATH").unwrap_or_default()))
        .stdin(std::process::Stdio::null())
        .stdout(std::fs::File::create(&log).expect("log"))
        .stderr(std::fs::OpenOptions::new().append(true).open(&log).expect("log"));
    for (k, v) in env {
        cmd.env(k, v);
    }
    let mut child = cmd.spawn().expect("run the sbatch script");
    let start = std::time::Instant::now();
    let status = loop {
        if let Some(s) = child.try_wait().expect("wait") {
            break s;
        }
        if start.elapsed() > Duration::from_secs(120) {
            let _ = child.kill();
            panic!("workers.sbatch did not exit:\n{}", std::fs::read_to_string(&log).unwrap_or_default());
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    (status, std::fs::read_to_string(&log).unwrap_or_default())
}

#[test]
fn slurm_worker_script_runs_a_calibration_and_exits_when_idle() {
    let dir = scratch("slurm");
    let server = Server::start(&dir, "serve", "127.0.0.1:0", &dir.join("c.db"), &[]);
    let id = submit(&server.url, &dir, &[]);
    // the coordinator's URL through the file coordinator.sbatch writes, the token through its file
    let state = dir.join("state");
    std::fs::create_dir_all(&state).expect("state dir");
    std::fs::write(state.join("coordinator.url"), format!("{}\n", server.url)).expect("url file");
    std::fs::create_dir_all(dir.join(".config/cryofit")).expect("config dir");
    std::fs::write(dir.join(".config/cryofit/worker-token"), "unused-on-loopback\n").expect("token file");
    let (status, log) = run_sbatch(
        &dir,
        &[
            ("SLURM_CPUS_PER_TASK", "2".into()),
            ("SLURM_ARRAY_TASK_ID", "0".into()),
            ("CRYOFIT_STATE_DIR", state.display().to_string()),
            ("CRYOFIT_IDLE_S", "2".into()),
        ],
    );
    assert!(status.success(), "workers.sbatch failed:\n{log}");
    assert!(log.contains("2 slots"), "the task should use SLURM_CPUS_PER_TASK slots:\n{log}");
    let c = get_json(&format!("{}/api/v1/calibrations/{id}", server.url), None);
    assert_eq!(c["status"], "completed", "{c}\n{log}");
    check_history(&server.url, id, 18);

    // no coordinator to be found: a clear error, not a hang
    let (status, log) = run_sbatch(
        &dir,
        &[("CRYOFIT_STATE_DIR", dir.join("nowhere").display().to_string()), ("CRYOFIT_WAIT_S", "0".into())],
    );
    assert!(!status.success(), "should fail without a coordinator:\n{log}");
    assert!(log.contains("did not appear"), "{log}");
}

#[test]
fn healthcheck_command_reports_a_coordinator() {
    let dir = scratch("healthcheck");
    let server = Server::start(&dir, "serve", "127.0.0.1:0", &dir.join("c.db"), &[]);
    let run = |url: &str| {
        Command::new(cryofit_bin())
            .args(["healthcheck", "--url", url, "--timeout", "5"])
            .output()
            .expect("run cryofit healthcheck")
    };
    let ok = run(&format!("{}/healthz", server.url));
    assert!(ok.status.success(), "{}", String::from_utf8_lossy(&ok.stderr));
    assert!(String::from_utf8_lossy(&ok.stdout).starts_with("ok: "));
    // a path that is not a health report, and a port where nothing listens
    let wrong = run(&format!("{}/api/v1/nothing", server.url));
    assert!(!wrong.status.success());
    assert!(String::from_utf8_lossy(&wrong.stderr).contains("answered"), "{}", String::from_utf8_lossy(&wrong.stderr));
    let free = std::net::TcpListener::bind("127.0.0.1:0").expect("bind").local_addr().expect("addr");
    let closed = run(&format!("http://{free}/healthz"));
    assert!(!closed.status.success());
    assert!(
        String::from_utf8_lossy(&closed.stderr).contains("cannot connect"),
        "{}",
        String::from_utf8_lossy(&closed.stderr)
    );
}

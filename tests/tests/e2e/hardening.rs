//! What an attacker or a careless user tried on the coordinator and the workers: each
//! test makes the attack and checks that the coordinator refuses it with a 4xx naming the field,
//! keeps one process per database and keeps answering, and that workers retry, drain and share.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::{TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

use serde_json::Value;

use crate::common::*;

/// Writes a calibration of the tiny case into `dir` with the given `[[stages]]` text, the case
/// changed by `case_edit` (from, to) pairs and the data with `extra_data` rows appended.
fn calibration_file(dir: &Path, name: &str, stages: &str, case_edit: &[(&str, &str)], extra_data: &str) -> PathBuf {
    let mut case = std::fs::read_to_string(fixture("tiny.toml")).expect("tiny case");
    for (from, to) in case_edit {
        assert!(case.contains(from), "tiny.toml has no `{from}`");
        case = case.replace(from, to);
    }
    let data = std::fs::read_to_string(fixture("tiny-data.csv")).expect("tiny data") + extra_data;
    std::fs::write(dir.join(format!("{name}-case.toml")), case).expect("write case");
    std::fs::write(dir.join(format!("{name}-data.csv")), data).expect("write data");
    let text = format!(
        "name = \"{name}\"\nseed = 7\nmax_evaluation_s = 300.0\n\n[[experiments]]\ncase = \"{name}-case.toml\"\n\
         data = \"{name}-data.csv\"\n\n[[parameters]]\nname = \"Gwsc\"\nlower = 0.5\nupper = 2.0\n\n\
         [[parameters]]\nname = \"hg0sc\"\n\n[weights]\nwall_temperature_k = {{ weight = 1.0, sigma = 1.0 }}\n\n{stages}"
    );
    let file = dir.join(format!("{name}.toml"));
    std::fs::write(&file, text).expect("write calibration");
    file
}

/// Runs `cryofit submit FILE`; returns (exit success, stderr).
fn submit_file(dir: &Path, url: &str, file: &Path) -> (bool, String) {
    let tag = file.file_stem().map_or_else(String::new, |s| s.to_string_lossy().into_owned());
    let mut p = Proc::start(
        &format!("submit-{tag}"),
        dir,
        &["submit", &file.display().to_string(), "--coordinator", url, "--json"],
        &[],
    );
    let status = p.wait(Duration::from_secs(60)).expect("submit finished");
    (status.success(), p.logs())
}

#[test]
fn oversized_calibrations_are_refused_with_a_4xx_naming_the_field_and_the_coordinator_stays_up() {
    let dir = scratch("oversized");
    let server = Server::start(&dir, "serve", "127.0.0.1:0", &dir.join("c.db"), &[]);
    let url = &server.url;
    let big = "[[stages]]\nalgorithm = \"cmaes\"\nbudget = 9000000000000000000\n\n";
    let cases = [
        (
            calibration_file(
                &dir,
                "morris",
                "[[stages]]\nalgorithm = \"morris\"\nbudget = 500\ntrajectories = 100000000000000\n",
                &[],
                "",
            ),
            "stages[0].trajectories",
        ),
        (
            calibration_file(
                &dir,
                "mcmc",
                "[[stages]]\nalgorithm = \"mcmc\"\nbudget = 500\nwalkers = 100000000000000\n",
                &[],
                "",
            ),
            "stages[0].walkers",
        ),
        (calibration_file(&dir, "budgets", &big.repeat(3), &[], ""), "stages[0].budget"),
        (
            calibration_file(
                &dir,
                "interval",
                "[[stages]]\nalgorithm = \"cmaes\"\nbudget = 6\n",
                &[("output_interval_s = 1.0", "output_interval_s = 1e-300")],
                "",
            ),
            "time.output_interval_s",
        ),
    ];
    for (file, field) in &cases {
        let (ok, log) = submit_file(&dir, url, file);
        assert!(!ok, "{}: accepted", file.display());
        assert!(
            log.contains("422") && log.contains(field),
            "{}: the refusal should name {field}: {log}",
            file.display()
        );
        let health = get_json(&format!("{url}/healthz"), None);
        assert_eq!(health["status"], "ok", "after {}: {health}", file.display());
    }
    let calibrations = get_json(&format!("{url}/api/v1/calibrations"), None);
    assert_eq!(calibrations["items"].as_array().map(Vec::len), Some(0), "nothing stored: {calibrations}");
    // the limits are in the OpenAPI document
    let doc = get_json(&format!("{url}/api/v1/openapi.json"), None);
    assert_eq!(doc["info"]["x-cryofit-limits"]["max_stage_size"], 10_000, "{}", doc["info"]);
    assert!(doc["info"]["description"].as_str().is_some_and(|d| d.contains("--max-budget")), "{}", doc["info"]);
}

#[test]
fn limits_are_set_at_serve_and_shown_in_the_openapi_document() {
    let dir = scratch("limits-flag");
    let server = Server::start(&dir, "serve", "127.0.0.1:0", &dir.join("c.db"), &[("CRYOFIT_MAX_BUDGET", "12")]);
    let doc = get_json(&format!("{}/api/v1/openapi.json", server.url), None);
    assert_eq!(doc["info"]["x-cryofit-limits"]["max_budget"], 12, "{}", doc["info"]);
    // the tiny calibration asks for 18 evaluations
    let (ok, log) = submit_file(&dir, &server.url, &fixture("tiny-calibration.toml"));
    assert!(!ok && log.contains("at most 12 evaluations") && log.contains("stages[0].budget"), "{log}");
}

#[test]
fn a_body_over_the_limit_without_a_length_gets_a_413_that_reads_well() {
    use std::io::Read as _;
    let dir = scratch("chunked");
    let server = Server::start(&dir, "serve", "127.0.0.1:0", &dir.join("c.db"), &[("CRYOFIT_BODY_LIMIT", "2048")]);
    // a body of unknown length (chunked): the limit is found while reading it
    let body = reqwest::blocking::Body::new(std::io::repeat(b' ').take(10_000));
    let r = http()
        .post(format!("{}/api/v1/experiments", server.url))
        .header("Content-Type", "application/json")
        .body(body)
        .send()
        .expect("POST");
    assert_eq!(r.status().as_u16(), 413);
    let v: Value = r.json().expect("JSON error");
    assert_eq!(v["error"]["message"], "the body exceeds the limit of 2048 bytes", "{v}");
}

#[test]
fn a_second_coordinator_on_the_same_database_exits_naming_the_first() {
    let dir = scratch("second");
    let db = dir.join("c.db");
    let mut first = Server::start(&dir, "serve-1", "127.0.0.1:0", &db, &[]);
    let pid = first.proc.pid().expect("running");
    let mut second =
        Proc::start("serve-2", &dir, &["serve", "--bind", "127.0.0.1:0", "--database", &db.display().to_string()], &[]);
    let status = second.wait(Duration::from_secs(20)).expect("the second coordinator exits within seconds");
    assert!(!status.success());
    let log = second.logs();
    assert!(log.contains("another coordinator serves this database"), "{log}");
    assert!(log.contains(&format!("pid {pid}")) && log.contains(&first.addr), "names the holder: {log}");
    assert!(!second.stdout().contains("listening on"), "{}", second.stdout());
    assert_eq!(get_json(&format!("{}/healthz", first.url), None)["status"], "ok");
    // a clean stop gives the lock up: the next coordinator starts at once
    first.proc.terminate();
    assert!(first.proc.wait(Duration::from_secs(20)).is_some_and(|s| s.success()));
    let third = Server::start(&dir, "serve-3", "127.0.0.1:0", &db, &[]);
    assert_eq!(get_json(&format!("{}/healthz", third.url), None)["status"], "ok");
}

#[test]
fn identical_tokens_and_an_unwritable_database_are_refused_at_start() {
    let dir = scratch("refused-start");
    let same = [("CRYOFIT_CLIENT_TOKEN", "one-token"), ("CRYOFIT_WORKER_TOKEN", "one-token")];
    let mut p = Proc::start("serve-same", &dir, &["serve", "--bind", "127.0.0.1:0"], &same);
    assert!(!p.wait(Duration::from_secs(20)).expect("exits").success());
    assert!(p.logs().contains("are the same"), "{}", p.logs());
    // create a database, then serve it read-only
    let db = dir.join("c.db");
    let mut s = Server::start(&dir, "serve-create", "127.0.0.1:0", &db, &[]);
    s.proc.terminate();
    assert!(s.proc.wait(Duration::from_secs(20)).is_some());
    let ro = format!("sqlite://{}?mode=ro", db.display());
    let mut p = Proc::start("serve-ro", &dir, &["serve", "--bind", "127.0.0.1:0", "--database", &ro], &[]);
    assert!(!p.wait(Duration::from_secs(20)).expect("exits").success());
    assert!(p.logs().contains("cannot be written"), "{}", p.logs());
}

/// An HTTP/1.1 request: method, path, headers (names lower-cased), body.
type HttpRequest = (String, String, Vec<(String, String)>, Vec<u8>);

/// Reads one HTTP/1.1 request; `None` at the end of the connection.
fn read_request(r: &mut BufReader<TcpStream>) -> Option<HttpRequest> {
    let mut line = String::new();
    if r.read_line(&mut line).ok()? == 0 {
        return None;
    }
    let mut parts = line.split_whitespace();
    let (method, path) = (parts.next()?.to_string(), parts.next()?.to_string());
    let mut headers = Vec::new();
    loop {
        let mut h = String::new();
        r.read_line(&mut h).ok()?;
        let h = h.trim_end();
        if h.is_empty() {
            break;
        }
        let (k, v) = h.split_once(':')?;
        headers.push((k.trim().to_ascii_lowercase(), v.trim().to_string()));
    }
    let len = headers.iter().find(|(k, _)| k == "content-length").and_then(|(_, v)| v.parse().ok()).unwrap_or(0);
    let mut body = vec![0; len];
    r.read_exact(&mut body).ok()?;
    Some((method, path, headers, body))
}

/// A proxy in front of `upstream` that answers 429 to the first `refuse` experiment downloads;
/// returns its URL and the count of refusals made.
fn flaky_proxy(upstream: String, refuse: usize) -> (String, Arc<AtomicUsize>) {
    let listener = TcpListener::bind("127.0.0.1:0").expect("bind");
    let url = format!("http://{}", listener.local_addr().expect("addr"));
    let refused = Arc::new(AtomicUsize::new(0));
    let count = refused.clone();
    std::thread::spawn(move || {
        for stream in listener.incoming().flatten() {
            let (upstream, count) = (upstream.clone(), count.clone());
            std::thread::spawn(move || {
                let client = http();
                let mut out = stream.try_clone().expect("clone");
                let mut reader = BufReader::new(stream);
                while let Some((method, path, headers, body)) = read_request(&mut reader) {
                    let download = method == "GET" && path.starts_with("/api/v1/experiments/");
                    let (status, text) = if download
                        && count
                            .fetch_update(Ordering::SeqCst, Ordering::SeqCst, |n| (n < refuse).then_some(n + 1))
                            .is_ok()
                    {
                        (429, r#"{"error":{"code":"rate_limited","message":"slow down"}}"#.to_string())
                    } else {
                        let mut req = client.request(method.parse().expect("method"), format!("{upstream}{path}"));
                        for (k, v) in &headers {
                            if matches!(k.as_str(), "content-type" | "authorization" | "accept") {
                                req = req.header(k.as_str(), v.as_str());
                            }
                        }
                        match req.body(body).send() {
                            Ok(r) => (r.status().as_u16(), r.text().unwrap_or_default()),
                            Err(_) => (502, String::new()),
                        }
                    };
                    let head = format!(
                        "HTTP/1.1 {status} X\r\ncontent-type: application/json\r\ncontent-length: {}\r\n\r\n",
                        text.len()
                    );
                    if out.write_all(head.as_bytes()).and_then(|_| out.write_all(text.as_bytes())).is_err() {
                        break;
                    }
                }
            });
        }
    });
    (url, refused)
}

#[test]
fn a_worker_retries_a_refused_experiment_download_and_no_job_fails_for_it() {
    let dir = scratch("flaky-download");
    let server = Server::start(&dir, "serve", "127.0.0.1:0", &dir.join("c.db"), &[]);
    let (proxy, refused) = flaky_proxy(server.url.clone(), 3);
    let _w = worker(&dir, "work-1", &proxy, "30");
    let id = submit(&server.url, &dir, &[]);
    let c = wait_for(&server.url, id, Duration::from_secs(90), |c| c["status"] != "running");
    assert_eq!(c["status"], "completed", "{c}");
    assert_eq!(c["failed_evaluations"], 0, "{c}");
    check_history(&server.url, id, 18);
    assert_eq!(refused.load(Ordering::SeqCst), 3, "the worker met the 429s");
}

#[test]
fn a_worker_honours_sigterm_within_its_drain_timeout_mid_evaluation() {
    let dir = scratch("drain");
    let server = Server::start(&dir, "serve", "127.0.0.1:0", &dir.join("c.db"), &[]);
    // a case of 100 cells over 10^5 s with data to the end: one evaluation takes a minute or more
    let file = calibration_file(
        &dir,
        "slow",
        "[[stages]]\nalgorithm = \"cmaes\"\nbudget = 6\npopulation = 6\n",
        &[
            ("cells = 5", "cells = 100"),
            ("end_s = 8.0", "end_s = 100000.0"),
            ("output_interval_s = 1.0", "output_interval_s = 100.0"),
            ("profile_interval_s = 8.0", "profile_interval_s = 100000.0"),
        ],
        "100000,TS1,6.1,wall_temperature_k,77.0\n",
    );
    let (ok, log) = submit_file(&dir, &server.url, &file);
    assert!(ok, "{log}");
    let mut w = Proc::start(
        "work-slow",
        &dir,
        &["work", "--coordinator", &server.url, "--slots", "1", "--drain-timeout", "1"],
        &[],
    );
    let deadline = Instant::now() + Duration::from_secs(30);
    while metric(&server.url, "cryofit_leased_jobs") == 0 {
        assert!(Instant::now() < deadline, "no job was leased: {}", w.logs());
        std::thread::sleep(Duration::from_millis(50));
    }
    std::thread::sleep(Duration::from_millis(500));
    w.terminate();
    let status = w.wait(Duration::from_secs(20)).expect("the worker exits within seconds of SIGTERM");
    assert!(status.success(), "{}", w.logs());
    assert!(w.logs().contains("drain timeout"), "{}", w.logs());
    let c = get_json(&format!("{}/api/v1/calibrations/1", server.url), None);
    assert_eq!(c["evaluations"], 0, "the abandoned evaluation is not counted: {c}");
}

#[test]
fn dashboard_figures_are_drawn_once_for_concurrent_viewers() {
    let dir = scratch("single-flight");
    let server = Server::start(&dir, "serve", "127.0.0.1:0", &dir.join("c.db"), &[]);
    let _w = worker(&dir, "work-1", &server.url, "30");
    let id = submit(&server.url, &dir, &[]);
    let c = wait_for(&server.url, id, Duration::from_secs(60), |c| c["status"] != "running");
    assert_eq!(c["status"], "completed", "{c}");
    let url = format!("{}/calibrations/{id}", server.url);
    let views: Vec<_> = (0..4)
        .map(|_| {
            let url = url.clone();
            std::thread::spawn(move || http().get(&url).send().map(|r| r.status().as_u16()).unwrap_or(0))
        })
        .collect();
    for v in views {
        assert_eq!(v.join().expect("viewer"), 200);
    }
    assert_eq!(http().get(&url).send().map(|r| r.status().as_u16()).unwrap_or(0), 200);
    assert_eq!(metric(&server.url, "cryofit_figure_builds_total"), 1, "one drawing for five views");
}

#[test]
fn every_answer_carries_the_security_headers() {
    let dir = scratch("headers");
    let server = Server::start(&dir, "serve", "127.0.0.1:0", &dir.join("c.db"), &[]);
    for path in ["/", "/workers", "/healthz", "/api/v1/calibrations/99", "/nowhere", "/dashboard.js"] {
        let r = http().get(format!("{}{path}", server.url)).send().expect("GET");
        let h = |n: &str| r.headers().get(n).and_then(|v| v.to_str().ok()).unwrap_or_default().to_string();
        assert!(h("content-security-policy").contains("script-src 'self'"), "{path}");
        assert!(h("content-security-policy").contains("frame-ancestors 'none'"), "{path}");
        assert_eq!(h("x-frame-options"), "DENY", "{path}");
        assert_eq!(h("x-content-type-options"), "nosniff", "{path}");
    }
    let home = http().get(format!("{}/", server.url)).send().expect("GET").text().expect("body");
    assert!(home.contains("<script src=\"/dashboard.js\">") && !home.contains("<script>"), "no inline script");
}

/// The Set-Cookie value of a sign-in, and the cookie to send back.
fn sign_in(url: &str, form: &str) -> (u16, Option<String>, String) {
    let r = reqwest::blocking::Client::builder()
        .redirect(reqwest::redirect::Policy::none())
        .build()
        .expect("client")
        .post(format!("{url}/signin"))
        .header("Content-Type", "application/x-www-form-urlencoded")
        .body(form.to_string())
        .send()
        .expect("POST /signin");
    let location = r.headers().get("location").and_then(|v| v.to_str().ok()).map(str::to_string);
    let set = r.headers().get("set-cookie").and_then(|v| v.to_str().ok()).unwrap_or_default().to_string();
    (r.status().as_u16(), location, set)
}

fn page_status(url: &str, cookie: &str) -> u16 {
    http().get(url).header("Cookie", cookie).send().map(|r| r.status().as_u16()).unwrap_or(0)
}

#[test]
fn the_session_cookie_is_a_revocable_random_id_not_the_token() {
    let dir = scratch("session");
    let token = "client-s3cret";
    let env = [
        ("CRYOFIT_CLIENT_TOKEN", token),
        ("CRYOFIT_WORKER_TOKEN", "worker-s3cret"),
        ("CRYOFIT_SECURE_COOKIES", "true"),
    ];
    let server = Server::start(&dir, "serve", "127.0.0.1:0", &dir.join("c.db"), &env);
    let url = &server.url;
    let (status, location, set) = sign_in(url, &format!("token={token}&next=%2Fworkers"));
    assert_eq!((status, location.as_deref()), (303, Some("/workers")), "{set}");
    let hex: String = token.bytes().map(|b| format!("{b:02x}")).collect();
    assert!(!set.contains(token) && !set.contains(&hex), "the cookie holds the token: {set}");
    for attr in ["HttpOnly", "SameSite=Strict", "Secure", "Max-Age=43200"] {
        assert!(set.contains(attr), "{attr} missing: {set}");
    }
    let cookie = set.split(';').next().expect("name=value").to_string();
    let value = cookie.trim_start_matches("cryofit_session=");
    assert_eq!(value.len(), 64, "{cookie}");
    assert_eq!(page_status(&format!("{url}/workers"), &cookie), 200);
    // a second sign-in is another session
    let (_, _, other) = sign_in(url, &format!("token={token}"));
    assert_ne!(other.split(';').next(), Some(cookie.as_str()));
    // sign-out revokes the session on the server, not only in this browser
    let out = http().post(format!("{url}/signout")).header("Cookie", &cookie).send().expect("sign out");
    assert!(out.status().is_success() || out.status().is_redirection());
    assert_eq!(page_status(&format!("{url}/workers"), &cookie), 401, "a revoked session is refused");
    // `next` with a TAB (a browser drops it: `/\t/evil` would become `//evil`) goes home
    let (_, location, _) = sign_in(url, &format!("token={token}&next=%2F%09%2Fevil.example"));
    assert_eq!(location.as_deref(), Some("/"));
    let body: Value = http()
        .get(format!("{url}/api/v1/calibrations"))
        .header("Cookie", &cookie)
        .send()
        .expect("GET")
        .json()
        .expect("json");
    assert_eq!(body["error"]["code"], "unauthorized", "the cookie is not an API token");
}

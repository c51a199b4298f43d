//! Bad input, authentication and random bodies: 4xx JSON errors naming the problem, nothing
//! stored, never a 5xx.

use proptest::prelude::*;
use serde_json::{Value, json};

use crate::common::*;

/// Sends `method url` with an optional body and token; returns (status, JSON body).
fn send(method: &str, url: &str, body: Option<Vec<u8>>, token: Option<&str>) -> (u16, Value) {
    let client = http();
    let mut req = client.request(method.parse().expect("method"), url);
    if let Some(t) = token {
        req = req.bearer_auth(t);
    }
    if let Some(b) = body {
        req = req.header("content-type", "application/json").body(b);
    }
    let resp = req.send().expect("request");
    let status = resp.status().as_u16();
    let text = resp.text().unwrap_or_default();
    (status, serde_json::from_str(&text).unwrap_or(Value::String(text)))
}

/// POSTs a body of `len` spaces over a raw connection (writing from another thread, ignoring a
/// closed connection) and reads the answer: (status, JSON body).
fn post_raw(addr: &str, path: &str, len: usize) -> (u16, Value) {
    use std::io::{Read, Write};
    let mut stream = std::net::TcpStream::connect(addr).expect("connect");
    stream.set_read_timeout(Some(std::time::Duration::from_secs(30))).unwrap();
    let head = format!(
        "POST {path} HTTP/1.1\r\nHost: {addr}\r\nContent-Type: application/json\r\nContent-Length: {len}\r\n\r\n"
    );
    stream.write_all(head.as_bytes()).expect("write head");
    let mut writer = stream.try_clone().expect("clone");
    let t = std::thread::spawn(move || {
        let chunk = vec![b' '; 1 << 20];
        let mut left = len;
        while left > 0 {
            let n = left.min(chunk.len());
            if writer.write_all(&chunk[..n]).is_err() {
                break;
            }
            left -= n;
        }
    });
    let mut buf = Vec::new();
    let mut tmp = [0u8; 4096];
    let (status, body) = loop {
        let n = stream.read(&mut tmp).expect("read answer");
        assert!(n > 0, "connection closed without an answer");
        buf.extend_from_slice(&tmp[..n]);
        let text = String::from_utf8_lossy(&buf).to_string();
        if let Some(end) = text.find("\r\n\r\n") {
            let headers = text[..end].to_ascii_lowercase();
            let status: u16 = headers.split_whitespace().nth(1).and_then(|s| s.parse().ok()).expect("status");
            let length: usize = headers
                .lines()
                .find_map(|l| l.strip_prefix("content-length:"))
                .and_then(|v| v.trim().parse().ok())
                .unwrap_or(0);
            if buf.len() >= end + 4 + length {
                break (status, String::from_utf8_lossy(&buf[end + 4..end + 4 + length]).to_string());
            }
        }
    };
    let _ = stream.shutdown(std::net::Shutdown::Both);
    let _ = t.join();
    (status, serde_json::from_str(&body).unwrap_or(Value::String(body)))
}

fn experiment_body() -> Value {
    json!({
        "name": "tiny",
        "case": std::fs::read_to_string(fixture("tiny.toml")).unwrap(),
        "data": std::fs::read_to_string(fixture("tiny-data.csv")).unwrap(),
    })
}

fn calibration_body(experiment: i64) -> Value {
    json!({
        "name": "t",
        "seed": 1,
        "experiments": [experiment],
        "parameters": [{"name": "Gwsc", "lower": 0.5, "upper": 2.0}],
        "weights": {"wall_temperature_k": {"weight": 1.0, "sigma": 1.0}},
        "stages": [{"algorithm": "cmaes", "budget": 6, "population": 6}]
    })
}

fn assert_error(r: &(u16, Value), status: u16, field: Option<&str>, needle: &str) {
    assert_eq!(r.0, status, "{:?}", r.1);
    let e = &r.1["error"];
    assert!(e["code"].is_string(), "{:?}", r.1);
    let msg = e["message"].as_str().unwrap_or_default();
    assert!(msg.contains(needle), "message `{msg}` lacks `{needle}`");
    if let Some(f) = field {
        assert_eq!(e["field"], f, "{:?}", r.1);
    }
}

#[test]
fn bad_input_gets_4xx_json_errors_and_nothing_is_stored() {
    let dir = scratch("bad-input");
    let s = Server::start(&dir, "serve", "127.0.0.1:0", &dir.join("c.db"), &[]);
    let api = format!("{}/api/v1", s.url);
    let post = |path: &str, body: &[u8]| send("POST", &format!("{api}{path}"), Some(body.to_vec()), None);

    let r = post("/experiments", b"{\"name\": ");
    assert_error(&r, 400, None, "malformed JSON");
    let mut e = experiment_body();
    e["extra"] = json!(1);
    assert_error(&post("/experiments", e.to_string().as_bytes()), 422, None, "unknown field `extra`");
    let mut e = experiment_body();
    e["case"] = json!("[fluid]\nname = \"nitrogen\"\n");
    assert_error(&post("/experiments", e.to_string().as_bytes()), 422, Some("case"), "case");
    let r = post("/experiments", experiment_body().to_string().as_bytes());
    assert_eq!(r.0, 201, "{:?}", r.1);
    let exp = r.1["id"].as_i64().unwrap();

    let mut c = calibration_body(exp);
    c["parameters"][0]["upper"] = json!(0.4);
    assert_error(&post("/calibrations", c.to_string().as_bytes()), 422, Some("parameters[0]"), "lower < upper");
    let mut c = calibration_body(exp);
    c["parameters"][0]["name"] = json!("Gwscc");
    assert_error(&post("/calibrations", c.to_string().as_bytes()), 422, Some("parameters[0].name"), "Gwscc");
    let c = calibration_body(exp + 100);
    assert_error(&post("/calibrations", c.to_string().as_bytes()), 422, Some("experiments[0]"), "does not exist");
    let mut c = calibration_body(exp);
    c["stages"][0]["walkers"] = json!(3);
    assert_error(&post("/calibrations", c.to_string().as_bytes()), 422, Some("stages[0].walkers"), "walkers");
    let text = calibration_body(exp).to_string().replace("\"upper\":2.0", "\"upper\":NaN");
    assert_error(&post("/calibrations", text.as_bytes()), 400, None, "malformed JSON");
    let text = calibration_body(exp).to_string().replace("\"upper\":2.0", "\"upper\":1e999");
    assert_error(&post("/calibrations", text.as_bytes()), 400, None, "malformed JSON");
    let mut c = calibration_body(exp);
    c["bogus"] = json!(true);
    assert_error(&post("/calibrations", c.to_string().as_bytes()), 422, None, "unknown field `bogus`");
    // 50 MB body: answered 413 before the body is read (the client sees the answer while writing)
    assert_error(&post_raw(&s.addr, "/api/v1/experiments", 50 * 1024 * 1024), 413, None, "exceeds the limit");

    // nothing stored but the one good experiment; the server still serves
    let cals = get_json(&format!("{api}/calibrations"), None);
    assert_eq!(cals["items"].as_array().unwrap().len(), 0, "{cals}");
    let exps = get_json(&format!("{api}/experiments"), None);
    assert_eq!(exps["items"].as_array().unwrap().len(), 1, "{exps}");
    assert_eq!(get_json(&format!("{}/healthz", s.url), None)["status"], "ok");
    // a limit above the maximum is clamped
    let page = get_json(&format!("{api}/experiments?limit=1000000"), None);
    assert_eq!(page["items"].as_array().unwrap().len(), 1);
}

#[test]
fn tokens_and_roles() {
    let dir = scratch("auth");
    let env = [("CRYOFIT_CLIENT_TOKEN", "client-secret"), ("CRYOFIT_WORKER_TOKEN", "worker-secret")];
    let s = Server::start(&dir, "serve", "127.0.0.1:0", &dir.join("c.db"), &env);
    let api = format!("{}/api/v1", s.url);
    let body = Some(b"{}".to_vec());
    assert_error(&send("GET", &format!("{api}/calibrations"), None, None), 401, None, "missing bearer token");
    assert_error(&send("GET", &format!("{api}/calibrations"), None, Some("nope")), 401, None, "not valid");
    assert_error(
        &send("POST", &format!("{api}/calibrations"), body.clone(), Some("worker-secret")),
        403,
        None,
        "client",
    );
    assert_error(&send("POST", &format!("{api}/jobs/claim"), body.clone(), Some("client-secret")), 403, None, "worker");
    assert_error(&send("POST", &format!("{api}/jobs/1/result"), body.clone(), None), 401, None, "bearer");
    // the right role reaches the handler (which then rejects the empty body)
    assert_eq!(send("POST", &format!("{api}/jobs/claim"), body, Some("worker-secret")).0, 422);
    assert_eq!(send("GET", &format!("{api}/calibrations"), None, Some("client-secret")).0, 200);
    assert_eq!(send("GET", &format!("{api}/experiments/1"), None, Some("worker-secret")).0, 404);
    assert_eq!(send("GET", &format!("{}/healthz", s.url), None, None).0, 200);
    assert_eq!(send("GET", &format!("{}/metrics", s.url), None, None).0, 200);
    assert_eq!(send("GET", &format!("{}/", s.url), None, None).0, 200);
    let doc = send("GET", &format!("{api}/openapi.json"), None, Some("client-secret"));
    assert_eq!(doc.1["openapi"].as_str().map(|v| v.starts_with("3.1")), Some(true), "{:?}", doc.1);
}

#[test]
fn refuses_a_public_bind_without_tokens() {
    let dir = scratch("public");
    let mut p = Proc::start("serve", &dir, &["serve", "--bind", "0.0.0.0:0", "--database", "c.db"], &[]);
    let status = p.wait(std::time::Duration::from_secs(20)).expect("exits");
    assert!(!status.success());
    assert!(p.logs().contains("without tokens"), "{}", p.logs());
}

/// `POST /jobs/results`: each bad item is named by its index and the whole batch is refused (no
/// result stored); a good batch is counted like single results, and a repeated one is stale.
#[test]
fn result_batches_are_validated_and_counted() {
    let dir = scratch("batch");
    let s = Server::start(&dir, "serve", "127.0.0.1:0", &dir.join("c.db"), &[]);
    let api = format!("{}/api/v1", s.url);
    let post =
        |path: &str, body: &Value| send("POST", &format!("{api}{path}"), Some(body.to_string().into_bytes()), None);
    let e = post("/experiments", &experiment_body());
    assert_eq!(e.0, 201, "{:?}", e.1);
    let c = post("/calibrations", &calibration_body(e.1["id"].as_i64().unwrap()));
    assert_eq!(c.0, 201, "{:?}", c.1);
    let claim = json!({"worker": "w", "slots": 2, "max_jobs": 2, "solver_version": env!("CARGO_PKG_VERSION"),
                       "fluid_hashes": {}});
    let claimed = post("/jobs/claim", &claim);
    assert_eq!(claimed.0, 200, "{:?}", claimed.1);
    // the calibration's fluid hash is not offered: refused, with the reason
    assert_eq!(claimed.1["jobs"].as_array().map(Vec::len), Some(0), "{:?}", claimed.1);
    let refused = claimed.1["refused"][0]["reason"].as_str().unwrap_or_default().to_string();
    assert!(refused.contains("fluid table"), "{refused}");
    let hashes = calibration_hashes(&s.url);
    let claim = json!({"worker": "w", "slots": 2, "max_jobs": 2, "solver_version": env!("CARGO_PKG_VERSION"),
                       "fluid_hashes": hashes});
    let claimed = post("/jobs/claim", &claim);
    let jobs = claimed.1["jobs"].as_array().cloned().unwrap_or_default();
    assert_eq!(jobs.len(), 2, "{:?}", claimed.1);
    let item = |j: &Value, cost: Value| json!({"job_id": j["id"], "lease_id": j["lease_id"], "outcome": {"status": "ok", "cost": cost}});
    let bad = [
        (json!({"results": []}), "results", "at least one"),
        (
            json!({"results": [item(&jobs[0], json!(1.0)), item(&jobs[1], json!(-1.0))]}),
            "results[1].outcome.cost",
            "finite",
        ),
        (json!({"results": [item(&jobs[0], json!(1.0)), item(&jobs[0], json!(1.0))]}), "results[1].job_id", "twice"),
        (
            json!({"results": [item(&jobs[0], json!(1.0)), item(&json!({"id": 999_999, "lease_id": "x"}), json!(1.0))]}),
            "results[1].job_id",
            "does not exist",
        ),
    ];
    for (body, field, needle) in &bad {
        assert_error(&post("/jobs/results", body), 422, Some(field), needle);
    }
    let id = c.1["id"].as_i64().unwrap();
    let results = |id: i64| send("GET", &format!("{api}/calibrations/{id}/results"), None, None).1;
    assert_eq!(results(id)["items"].as_array().map(Vec::len), Some(0), "a refused batch stored results");
    let good = json!({"results": [item(&jobs[0], json!(1.5)), item(&jobs[1], json!(2.5))]});
    let r = post("/jobs/results", &good);
    assert_eq!(r.0, 200, "{:?}", r.1);
    assert_eq!(r.1["results"], json!([{"status": "ok", "counted": true}, {"status": "ok", "counted": true}]));
    let r = post("/jobs/results", &good);
    assert_eq!(r.1["results"], json!([{"status": "stale", "counted": false}, {"status": "stale", "counted": false}]));
    let cal = send("GET", &format!("{api}/calibrations/{id}"), None, None).1;
    assert_eq!(cal["evaluations"], 2, "{cal}");
    assert_eq!(results(id)["items"].as_array().map(Vec::len), Some(4));
}

/// The fluid hashes a calibration needs, as its record lists them.
fn calibration_hashes(url: &str) -> Value {
    let cal = send("GET", &format!("{url}/api/v1/calibrations/1"), None, None).1;
    cal["fluid_hashes"].clone()
}

fn endpoints() -> Vec<(&'static str, &'static str)> {
    vec![
        ("POST", "/experiments"),
        ("GET", "/experiments"),
        ("GET", "/experiments/1"),
        ("POST", "/calibrations"),
        ("GET", "/calibrations"),
        ("GET", "/calibrations/1"),
        ("POST", "/calibrations/1/cancel"),
        ("GET", "/calibrations/1/parameter-sets"),
        ("GET", "/calibrations/1/results"),
        ("POST", "/jobs/claim"),
        ("POST", "/jobs/1/heartbeat"),
        ("POST", "/jobs/1/result"),
        ("POST", "/jobs/results"),
    ]
}

fn json_value() -> impl Strategy<Value = Value> {
    let leaf = prop_oneof![
        Just(Value::Null),
        any::<bool>().prop_map(Value::Bool),
        any::<i64>().prop_map(|i| json!(i)),
        (-1e6f64..1e6).prop_map(|f| json!(f)),
        "[a-z_]{0,12}".prop_map(Value::String),
    ];
    leaf.prop_recursive(3, 24, 6, |inner| {
        prop_oneof![
            prop::collection::vec(inner.clone(), 0..4).prop_map(Value::Array),
            prop::collection::btree_map(
                prop_oneof![
                    Just("name".to_string()),
                    Just("experiments".to_string()),
                    Just("parameters".to_string()),
                    Just("stages".to_string()),
                    Just("lease_id".to_string()),
                    Just("outcome".to_string()),
                    Just("worker".to_string()),
                    Just("slots".to_string()),
                    Just("results".to_string()),
                    Just("job_id".to_string()),
                    "[a-z]{1,6}"
                ],
                inner,
                0..5
            )
            .prop_map(|m| Value::Object(m.into_iter().collect())),
        ]
    })
}

#[test]
fn random_bodies_never_get_a_5xx() {
    let dir = scratch("fuzz");
    let s = Server::start(&dir, "serve", "127.0.0.1:0", &dir.join("c.db"), &[]);
    let api = format!("{}/api/v1", s.url);
    // something to hit: an experiment
    let r = send("POST", &format!("{api}/experiments"), Some(experiment_body().to_string().into_bytes()), None);
    assert_eq!(r.0, 201);
    let body =
        prop_oneof![json_value().prop_map(|v| v.to_string().into_bytes()), prop::collection::vec(any::<u8>(), 0..64),];
    let mut runner = proptest::test_runner::TestRunner::new(ProptestConfig { cases: 200, ..ProptestConfig::default() });
    runner
        .run(&(0..endpoints().len(), body, "[a-z0-9=&]{0,12}"), |(k, body, query)| {
            let (method, path) = endpoints()[k];
            let url = format!("{api}{path}?{query}");
            let b = (method == "POST").then_some(body);
            let (status, v) = send(method, &url, b, None);
            prop_assert!(status < 500, "{method} {url}: {status} {v}");
            if status >= 400 {
                prop_assert!(v["error"]["message"].is_string(), "{method} {url}: {status} {v}");
            }
            Ok(())
        })
        .unwrap();
}

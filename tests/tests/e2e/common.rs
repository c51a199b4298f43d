//! HTTP helpers shared by the test modules.

use std::time::{Duration, Instant};

use serde_json::Value;

pub use cryofit_tests::*;

/// A blocking HTTP client.
pub fn http() -> reqwest::blocking::Client {
    reqwest::blocking::Client::builder().timeout(Duration::from_secs(30)).build().expect("http client")
}

/// GET `url` as JSON, asserting 200.
pub fn get_json(url: &str, token: Option<&str>) -> Value {
    let mut req = http().get(url);
    if let Some(t) = token {
        req = req.bearer_auth(t);
    }
    let resp = req.send().expect("GET");
    let status = resp.status();
    let text = resp.text().expect("body");
    assert_eq!(status.as_u16(), 200, "GET {url}: {text}");
    serde_json::from_str(&text).expect("JSON body")
}

/// Runs `cryofit submit --json` of the tiny calibration; returns the calibration id.
pub fn submit(url: &str, dir: &std::path::Path, env: &[(&str, &str)]) -> i64 {
    let mut p = Proc::start(
        "submit",
        dir,
        &["submit", &fixture("tiny-calibration.toml").display().to_string(), "--coordinator", url, "--json"],
        env,
    );
    let status = p.wait(Duration::from_secs(30)).expect("submit finished");
    assert!(status.success(), "submit failed: {}", p.logs());
    let out = p.stdout();
    let last = out.lines().last().expect("a line");
    let v: Value = serde_json::from_str(last).expect("last line is JSON");
    v["id"].as_i64().expect("id")
}

/// Polls a calibration until `done(calibration)` or the timeout; returns the last state.
pub fn wait_for(url: &str, id: i64, timeout: Duration, done: impl Fn(&Value) -> bool) -> Value {
    let start = Instant::now();
    loop {
        let c = get_json(&format!("{url}/api/v1/calibrations/{id}"), None);
        if done(&c) {
            return c;
        }
        assert!(start.elapsed() < timeout, "timed out waiting; calibration: {c}");
        std::thread::sleep(Duration::from_millis(100));
    }
}

/// Every page of a history endpoint.
pub fn all_items(url: &str, id: i64, what: &str) -> Vec<Value> {
    let mut items = Vec::new();
    let mut offset = 0;
    loop {
        let page = get_json(&format!("{url}/api/v1/calibrations/{id}/{what}?limit=7&offset={offset}"), None);
        items.extend(page["items"].as_array().expect("items").iter().cloned());
        match page["next_offset"].as_i64() {
            Some(n) => offset = n,
            None => return items,
        }
    }
}

/// Starts a worker with one slot.
pub fn worker(dir: &std::path::Path, name: &str, url: &str, idle_s: &str) -> Proc {
    Proc::start(name, dir, &["work", "--coordinator", url, "--slots", "1", "--exit-when-idle", idle_s], &[])
}

/// Checks a completed calibration's history: every parameter set costed exactly once.
pub fn check_history(url: &str, id: i64, budget: usize) {
    let sets = all_items(url, id, "parameter-sets");
    assert_eq!(sets.len(), budget, "parameter sets: {sets:?}");
    for s in &sets {
        assert_eq!(s["status"], "ok", "{s}");
        assert!(s["cost"].as_f64().is_some_and(|c| c.is_finite() && c >= 0.0), "{s}");
    }
    let results = all_items(url, id, "results");
    for s in &sets {
        let counted: Vec<&Value> =
            results.iter().filter(|r| r["parameter_set_id"] == s["id"] && r["status"] != "stale").collect();
        assert_eq!(counted.len(), 1, "parameter set {} counted {} times: {counted:?}", s["id"], counted.len());
        assert_eq!(counted[0]["cost"], s["cost"]);
    }
}

/// The value of a Prometheus counter or gauge without labels (0 when absent).
pub fn metric(url: &str, name: &str) -> u64 {
    let text = http().get(format!("{url}/metrics")).send().map(|r| r.text().unwrap_or_default()).unwrap_or_default();
    let prefix = format!("{name} ");
    text.lines()
        .find_map(|l| l.strip_prefix(prefix.as_str()))
        .and_then(|v| v.trim().parse::<f64>().ok())
        .map_or(0, |v| v as u64)
}

//! A calibration through coordinator and workers: completion, a worker killed mid-job, the
//! coordinator killed mid-calibration.

use std::time::Duration;

use crate::common::*;

const BUDGET: usize = 18;

fn completed(c: &serde_json::Value) -> bool {
    c["status"] != "running" && c["status"] != "queued"
}

/// Runs the tiny calibration undisturbed on two workers; returns (best cost, best parameters).
fn undisturbed(tag: &str) -> (serde_json::Value, serde_json::Value) {
    let dir = scratch(tag);
    let server = Server::start(&dir, "serve", "127.0.0.1:0", &dir.join("c.db"), &[]);
    let _w1 = worker(&dir, "work-1", &server.url, "30");
    let _w2 = worker(&dir, "work-2", &server.url, "30");
    let id = submit(&server.url, &dir, &[]);
    let c = wait_for(&server.url, id, Duration::from_secs(55), completed);
    assert_eq!(c["status"], "completed", "{c}");
    assert_eq!(c["evaluations"], BUDGET);
    check_history(&server.url, id, BUDGET);
    (c["best_cost"].clone(), c["best_parameters"].clone())
}

#[test]
fn calibration_completes_on_two_workers_with_full_history() {
    let (best, params) = undisturbed("complete");
    assert!(best.as_f64().is_some_and(f64::is_finite));
    assert!(params.as_object().is_some_and(|p| p.len() == 2), "{params}");
}

#[test]
fn killed_worker_jobs_are_released_after_lease_expiry() {
    let dir = scratch("worker-kill");
    let env = [("CRYOFIT_LEASE_S", "1.5")];
    let server = Server::start(&dir, "serve", "127.0.0.1:0", &dir.join("c.db"), &env);
    let mut doomed = worker(&dir, "work-doomed", &server.url, "30");
    let id = submit(&server.url, &dir, &[]);
    // wait until the doomed worker has reported some jobs and holds leases, then kill it
    wait_for(&server.url, id, Duration::from_secs(30), |c| c["evaluations"].as_i64().unwrap_or(0) >= 2);
    let deadline = std::time::Instant::now() + Duration::from_secs(10);
    while metric(&server.url, "cryofit_leased_jobs") == 0 && std::time::Instant::now() < deadline {
        std::thread::sleep(Duration::from_millis(5));
    }
    doomed.kill();
    // what it held when it died (on a loaded machine it may have reported everything first)
    let held = metric(&server.url, "cryofit_leased_jobs");
    let _w1 = worker(&dir, "work-1", &server.url, "30");
    let _w2 = worker(&dir, "work-2", &server.url, "30");
    let c = wait_for(&server.url, id, Duration::from_secs(55), completed);
    assert_eq!(c["status"], "completed", "{c}");
    check_history(&server.url, id, BUDGET);
    let expired = metric(&server.url, "cryofit_expired_leases_total");
    assert!(held == 0 || expired >= 1, "the killed worker held {held} leases, which should have expired");
}

#[test]
fn killed_coordinator_resumes_bit_identically() {
    let (best_ref, params_ref) = undisturbed("reference");
    let dir = scratch("coord-kill");
    let db = dir.join("c.db");
    let mut server = Server::start(&dir, "serve-1", "127.0.0.1:0", &db, &[]);
    let _w1 = worker(&dir, "work-1", &server.url, "60");
    let _w2 = worker(&dir, "work-2", &server.url, "60");
    let id = submit(&server.url, &dir, &[]);
    wait_for(&server.url, id, Duration::from_secs(30), |c| c["evaluations"].as_i64().unwrap_or(0) >= 7);
    server.proc.kill();
    std::thread::sleep(Duration::from_millis(300));
    let server2 = Server::start(&dir, "serve-2", &server.addr, &db, &[]);
    let c = wait_for(&server2.url, id, Duration::from_secs(55), completed);
    assert_eq!(c["status"], "completed", "{c}");
    check_history(&server2.url, id, BUDGET);
    // bit-identical: serde_json with float_roundtrip prints the shortest round-trip form
    assert_eq!(c["best_cost"].to_string(), best_ref.to_string());
    assert_eq!(c["best_parameters"].to_string(), params_ref.to_string());
}

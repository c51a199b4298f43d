//! The dashboard of a real coordinator: pages over plain HTTP while a calibration runs and after
//! it finished, sign-in when tokens are configured, and the calibration page rendered by headless
//! Chromium (plots present, no console message, a screenshot under `target/`).

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

use crate::common::*;

/// An HTTP client that does not follow redirects (the dashboard must not need them).
fn plain() -> reqwest::blocking::Client {
    reqwest::blocking::Client::builder()
        .timeout(Duration::from_secs(60))
        .redirect(reqwest::redirect::Policy::none())
        .build()
        .expect("http client")
}

/// GET with an optional cookie: (status, content type, Location header, body).
fn get(url: &str, cookie: Option<&str>) -> (u16, String, Option<String>, String) {
    let mut req = plain().get(url);
    if let Some(c) = cookie {
        req = req.header("Cookie", c);
    }
    let resp = req.send().expect("GET");
    let status = resp.status().as_u16();
    let header = |name: &str| resp.headers().get(name).and_then(|v| v.to_str().ok()).map(str::to_string);
    let (ctype, location) = (header("content-type").unwrap_or_default(), header("location"));
    (status, ctype, location, resp.text().expect("body"))
}

fn svg_count(html: &str) -> usize {
    html.matches("<svg").count()
}

/// The target directory the tests were built into (`target/`, or `CARGO_TARGET_DIR`).
fn target_dir() -> PathBuf {
    let exe = std::env::current_exe().expect("test executable");
    // target/<profile>/deps/<exe>
    exe.ancestors().nth(3).map(Path::to_path_buf).unwrap_or_else(|| workspace().join("target"))
}

/// Chromium's path, or `None` with the reason printed; in CI (`CI=true`) its absence fails.
fn chromium() -> Option<PathBuf> {
    let found = std::env::var_os("PATH").and_then(|paths| {
        std::env::split_paths(&paths)
            .flat_map(|d| ["chromium", "chromium-browser"].map(|n| d.join(n)))
            .find(|p| p.is_file())
    });
    if found.is_none() {
        let ci = std::env::var("CI").is_ok_and(|v| v == "true" || v == "1");
        assert!(!ci, "chromium is not installed: tools/setup.sh installs it (Debian package `chromium`)");
        eprintln!("skipping the browser part: chromium is not installed (tools/setup.sh installs it)");
    }
    found
}

/// Runs headless Chromium on `url` with `extra` arguments; returns (stdout, stderr).
fn run_chromium(bin: &Path, profile: &Path, url: &str, extra: &[&str]) -> (String, String) {
    let profile_arg = format!("--user-data-dir={}", profile.display());
    let out = Command::new("timeout")
        .arg("90")
        .arg(bin)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-background-networking",
            "--enable-logging=stderr",
            "--v=0",
            profile_arg.as_str(),
        ])
        .args(extra)
        .arg(url)
        .output()
        .expect("start chromium");
    let (stdout, stderr) =
        (String::from_utf8_lossy(&out.stdout).into_owned(), String::from_utf8_lossy(&out.stderr).into_owned());
    assert!(out.status.success(), "chromium failed on {url}: {}\n{stderr}", out.status);
    (stdout, stderr)
}

/// Console messages (errors, uncaught exceptions, warnings) in Chromium's log: the pages log none.
fn console_lines(stderr: &str) -> Vec<&str> {
    stderr.lines().filter(|l| l.contains(":CONSOLE") || l.contains("Uncaught")).collect()
}

#[test]
fn dashboard_follows_a_calibration_and_renders_in_chromium() {
    let dir = scratch("dashboard");
    let server = Server::start(&dir, "serve", "127.0.0.1:0", &dir.join("c.db"), &[]);
    let url = &server.url;

    let (status, ctype, location, home) = get(&format!("{url}/"), None);
    assert_eq!((status, location), (200, None), "{home}");
    assert!(ctype.starts_with("text/html"), "{ctype}");
    assert!(home.contains("No calibration yet"), "{home}");

    // submitted, no worker yet: running, and the page asks to be refreshed
    let id = submit(url, &dir, &[]);
    let (status, _, _, page) = get(&format!("{url}/calibrations/{id}"), None);
    assert_eq!(status, 200, "{page}");
    assert!(page.contains("status running") && page.contains("data-refresh="), "{page}");
    assert!(page.contains("Not drawn: no evaluation has finished yet"), "{page}");
    let (_, _, _, home) = get(&format!("{url}/"), None);
    assert!(home.contains(&format!("href=\"/calibrations/{id}\"")) && home.contains("running"), "{home}");

    // the running page in the browser, long enough (virtual time) for two refreshes to swap in
    let bin = chromium();
    let profile = dir.join("chromium-profile");
    if let Some(bin) = &bin {
        let page = format!("{url}/calibrations/{id}");
        let (dom, log) = run_chromium(bin, &profile, &page, &["--virtual-time-budget=12000", "--dump-dom"]);
        assert!(dom.contains("data-refresh=") && dom.contains("status running"), "{dom}");
        assert!(console_lines(&log).is_empty(), "console output: {:?}", console_lines(&log));
    }

    let _w1 = worker(&dir, "work-1", url, "30");
    let _w2 = worker(&dir, "work-2", url, "30");
    // part-way: the page shows progress and the cost history already
    let c = wait_for(url, id, Duration::from_secs(55), |c| c["evaluations"].as_i64().unwrap_or(0) >= 6);
    if c["status"] == "running" {
        let (_, _, _, page) = get(&format!("{url}/calibrations/{id}"), None);
        assert!(page.contains("<figure id=\"cost-history\"><h3>Best cost against evaluations</h3><svg"), "{page}");
    }
    let c = wait_for(url, id, Duration::from_secs(55), |c| c["status"] != "running" && c["status"] != "queued");
    assert_eq!(c["status"], "completed", "{c}");

    let (status, _, _, page) = get(&format!("{url}/calibrations/{id}"), None);
    assert_eq!(status, 200);
    assert!(page.contains("status completed") && !page.contains("data-refresh="), "{page}");
    // cost history, traces, model against data, boiling curves; no screening or posterior stage
    assert_eq!(svg_count(&page), 4, "{page}");
    assert!(page.contains("station TS3") && page.contains("wall heat flux (W/m²)"), "{page}");
    assert!(page.contains("Not drawn: the calibration has no sensitivity or Morris stage"), "{page}");

    let (status, ctype, _, csv) = get(&format!("{url}/calibrations/{id}/parameter-sets.csv"), None);
    assert_eq!(status, 200);
    assert!(ctype.starts_with("text/csv"), "{ctype}");
    assert_eq!(csv.lines().count(), 18 + 1, "{csv}");
    assert!(csv.starts_with("id,job,stage,status,cost,reason,Gwsc,hg0sc"), "{csv}");
    let (status, ctype, _, results) = get(&format!("{url}/calibrations/{id}/results.csv"), None);
    assert_eq!((status, ctype.starts_with("text/csv")), (200, true));
    assert!(results.lines().count() > 18, "{results}");
    let png = plain().get(format!("{url}/calibrations/{id}/figures/cost-history.png")).send().unwrap();
    assert_eq!(png.status().as_u16(), 200);
    assert_eq!(&png.bytes().unwrap()[..4], b"\x89PNG");
    let (status, _, _, _) = get(&format!("{url}/calibrations/{id}/figures/nothing.svg"), None);
    assert_eq!(status, 404);
    let (status, _, _, _) = get(&format!("{url}/calibrations/999"), None);
    assert_eq!(status, 404);

    let (_, _, _, workers) = get(&format!("{url}/workers"), None);
    // two workers, each with the results it reported
    assert_eq!(workers.matches("<tr><td>worker-").count(), 2, "{workers}");
    assert!(workers.contains("results/min"), "{workers}");
    let (_, _, _, exps) = get(&format!("{url}/experiments"), None);
    assert!(exps.contains("tiny"), "{exps}");
    let (status, _, _, exp) = get(&format!("{url}/experiments/1"), None);
    assert_eq!(status, 200);
    assert!(svg_count(&exp) >= 1 && exp.contains("measured wall temperature (K)") && exp.contains("[pipe]"), "{exp}");

    // the browser: plots render, nothing is logged to the console, a screenshot for people
    let Some(bin) = bin else { return };
    for page in ["/", &format!("/calibrations/{id}"), "/experiments/1", "/workers"] {
        let (dom, log) = run_chromium(&bin, &profile, &format!("{url}{page}"), &["--dump-dom"]);
        assert!(dom.contains("<main id=\"live\""), "{page}: {dom}");
        assert!(console_lines(&log).is_empty(), "{page}: console output: {:?}", console_lines(&log));
        if page.starts_with("/calibrations") {
            assert_eq!(svg_count(&dom), 4, "{page}: the plots did not render");
            assert!(dom.contains("<polyline") || dom.contains("<path"), "{page}: no plotted lines");
        }
    }
    let shot = target_dir().join("dashboard-calibration.png");
    let _ = std::fs::remove_file(&shot);
    let arg = format!("--screenshot={}", shot.display());
    let (_, log) =
        run_chromium(&bin, &profile, &format!("{url}/calibrations/{id}"), &[&arg, "--window-size=1400,2600"]);
    assert!(console_lines(&log).is_empty(), "console output: {:?}", console_lines(&log));
    let png = std::fs::read(&shot).unwrap_or_else(|e| panic!("no screenshot at {}: {e}", shot.display()));
    assert!(png.len() > 10_000 && png.starts_with(b"\x89PNG"), "{} bytes", png.len());
    eprintln!("dashboard screenshot: {}", shot.display());
}

#[test]
fn with_tokens_every_data_page_needs_the_sign_in_cookie() {
    let dir = scratch("dashboard-auth");
    let env = [("CRYOFIT_CLIENT_TOKEN", "client s3cret"), ("CRYOFIT_WORKER_TOKEN", "worker-s3cret")];
    let server = Server::start(&dir, "serve", "127.0.0.1:0", &dir.join("c.db"), &env);
    let url = &server.url;

    let (status, _, location, home) = get(&format!("{url}/"), None);
    assert_eq!((status, location), (200, None), "{home}");
    assert!(home.contains("<form method=\"post\" action=\"/signin\"") && !home.contains("Calibrations</h1>"), "{home}");
    for page in
        ["/calibrations/1", "/experiments", "/experiments/1/data.csv", "/workers", "/calibrations/1/results.csv"]
    {
        let (status, _, location, body) = get(&format!("{url}{page}"), None);
        assert_eq!((status, location), (401, None), "{page}: {body}");
        assert!(body.contains("action=\"/signin\"") && body.contains(&format!("value=\"{page}\"")), "{page}: {body}");
    }

    let sign_in = |form: &str| {
        plain()
            .post(format!("{url}/signin"))
            .header("Content-Type", "application/x-www-form-urlencoded")
            .body(form.to_string())
            .send()
            .expect("POST /signin")
    };
    let wrong = sign_in("token=worker-s3cret&next=%2Fworkers");
    assert_eq!(wrong.status().as_u16(), 401);
    assert!(wrong.headers().get("set-cookie").is_none());
    let right = sign_in("token=client+s3cret&next=%2Fworkers");
    assert_eq!(right.status().as_u16(), 303);
    assert_eq!(right.headers().get("location").and_then(|v| v.to_str().ok()), Some("/workers"));
    let set = right.headers().get("set-cookie").and_then(|v| v.to_str().ok()).expect("a cookie").to_string();
    assert!(set.contains("HttpOnly") && set.contains("SameSite=Strict"), "{set}");
    let cookie = set.split(';').next().unwrap().to_string();

    let (status, _, _, body) = get(&format!("{url}/workers"), Some(&cookie));
    assert_eq!(status, 200, "{body}");
    assert!(body.contains("<h1>Workers</h1>") && body.contains("Sign out"), "{body}");
    let (status, _, _, body) = get(&format!("{url}/"), Some(&cookie));
    assert_eq!(status, 200);
    assert!(body.contains("<h1>Calibrations</h1>"), "{body}");
    // a forged cookie and the worker token's cookie are refused; the API still wants its bearer token
    let worker_cookie =
        format!("cryofit_session={}", "worker-s3cret".bytes().map(|b| format!("{b:02x}")).collect::<String>());
    for c in ["cryofit_session=00ff", worker_cookie.as_str()] {
        let (status, _, _, _) = get(&format!("{url}/workers"), Some(c));
        assert_eq!(status, 401, "{c}");
    }
    let (status, _, _, _) = get(&format!("{url}/api/v1/calibrations"), Some(&cookie));
    assert_eq!(status, 401);
    let out = plain().post(format!("{url}/signout")).header("Cookie", &cookie).send().unwrap();
    assert_eq!(out.status().as_u16(), 303);
    let cleared = out.headers().get("set-cookie").and_then(|v| v.to_str().ok()).unwrap_or_default().to_string();
    assert!(cleared.contains("Max-Age=0"), "{cleared}");
}

//! Helpers of the end-to-end tests: start the real `cryofit` binary as coordinator and workers on
//! loopback ports, each process logging to a file that is printed only when a test fails.

#![warn(missing_docs)]

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::OnceLock;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

/// Root of the workspace.
pub fn workspace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).parent().map(Path::to_path_buf).unwrap_or_default()
}

/// A fixture file of this crate.
pub fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures").join(name)
}

/// The `cryofit` binary: `CRYOFIT_BIN` if set, else built once with `cargo build -p cryofit`
/// into this workspace's target directory (same profile as the tests).
pub fn cryofit_bin() -> PathBuf {
    static BIN: OnceLock<PathBuf> = OnceLock::new();
    BIN.get_or_init(|| {
        if let Some(p) = std::env::var_os("CRYOFIT_BIN") {
            return PathBuf::from(p);
        }
        // target/<profile>/deps/<test exe> → target/<profile>/cryofit
        let exe = std::env::current_exe().expect("test executable path");
        let profile_dir = exe.parent().and_then(Path::parent).expect("target/<profile>").to_path_buf();
        let release = profile_dir.file_name().is_some_and(|n| n == "release");
        let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
        let mut cmd = Command::new(cargo);
        cmd.current_dir(workspace()).args(["build", "-q", "-p", "cryofit", "--bin", "cryofit"]);
        if release {
            cmd.arg("--release");
        }
        let status = cmd.status().expect("run cargo build -p cryofit");
        assert!(status.success(), "cargo build -p cryofit failed");
        profile_dir.join("cryofit")
    })
    .clone()
}

/// A fresh scratch directory under the system temp dir.
pub fn scratch(tag: &str) -> PathBuf {
    static N: AtomicUsize = AtomicUsize::new(0);
    let dir = std::env::temp_dir().join(format!(
        "cryofit-e2e-{}-{tag}-{}",
        std::process::id(),
        N.fetch_add(1, Ordering::Relaxed)
    ));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("create scratch dir");
    dir
}

/// A running `cryofit` process whose output goes to a log file.
#[derive(Debug)]
pub struct Proc {
    /// What it is (`serve`, `work-1`).
    pub name: String,
    child: Option<Child>,
    /// Its stdout+stderr log.
    pub log: PathBuf,
    /// Its stdout.
    pub out: PathBuf,
}

impl Proc {
    /// Starts `cryofit ARGS` with extra environment, logging into `dir`.
    pub fn start(name: &str, dir: &Path, args: &[&str], env: &[(&str, &str)]) -> Self {
        let log = dir.join(format!("{name}.log"));
        let out = dir.join(format!("{name}.out"));
        let mut cmd = Command::new(cryofit_bin());
        cmd.args(args)
            .env_remove("CRYOFIT_CLIENT_TOKEN")
            .env_remove("CRYOFIT_WORKER_TOKEN")
            .env_remove("CRYOFIT_TOKEN")
            .env("RUST_LOG", "info")
            .stdin(Stdio::null())
            .stdout(std::fs::File::create(&out).expect("stdout file"))
            .stderr(std::fs::OpenOptions::new().create(true).append(true).open(&log).expect("log file"));
        for (k, v) in env {
            cmd.env(k, v);
        }
        let child = cmd.spawn().expect("start cryofit");
        Self { name: name.to_string(), child: Some(child), log, out }
    }

    /// Its process id, while it runs.
    pub fn pid(&self) -> Option<u32> {
        self.child.as_ref().map(Child::id)
    }

    /// Sends SIGKILL and waits.
    pub fn kill(&mut self) {
        if let Some(mut c) = self.child.take() {
            let _ = c.kill();
            let _ = c.wait();
        }
    }

    /// Sends SIGTERM (through `kill -TERM`) without waiting.
    pub fn terminate(&self) {
        if let Some(c) = &self.child {
            let _ = Command::new("kill").args(["-TERM", &c.id().to_string()]).status();
        }
    }

    /// Waits for the process to exit, up to `timeout`; returns its exit status.
    pub fn wait(&mut self, timeout: Duration) -> Option<std::process::ExitStatus> {
        let start = Instant::now();
        while start.elapsed() < timeout {
            if let Some(c) = &mut self.child
                && let Ok(Some(s)) = c.try_wait()
            {
                self.child = None;
                return Some(s);
            }
            std::thread::sleep(Duration::from_millis(50));
        }
        None
    }

    /// The stdout so far.
    pub fn stdout(&self) -> String {
        std::fs::read_to_string(&self.out).unwrap_or_default()
    }

    /// The log so far.
    pub fn logs(&self) -> String {
        std::fs::read_to_string(&self.log).unwrap_or_default()
    }
}

impl Drop for Proc {
    fn drop(&mut self) {
        self.kill();
        if std::thread::panicking() {
            eprintln!("----- {} stdout -----\n{}", self.name, self.stdout());
            eprintln!("----- {} log -----\n{}", self.name, self.logs());
        }
    }
}

/// A coordinator process and its URL.
#[derive(Debug)]
pub struct Server {
    /// The process.
    pub proc: Proc,
    /// `http://127.0.0.1:PORT`.
    pub url: String,
    /// The bind address used (for a restart on the same port).
    pub addr: String,
}

impl Server {
    /// Starts `cryofit serve` on `bind` (e.g. `127.0.0.1:0`) with `db`, waiting until it listens.
    pub fn start(dir: &Path, name: &str, bind: &str, db: &Path, env: &[(&str, &str)]) -> Self {
        let proc = Proc::start(name, dir, &["serve", "--bind", bind, "--database", &db.display().to_string()], env);
        let start = Instant::now();
        loop {
            if let Some(line) = proc.stdout().lines().find_map(|l| l.strip_prefix("listening on ").map(str::to_string))
            {
                let addr = line.trim_start_matches("http://").to_string();
                return Self { proc, url: line, addr };
            }
            assert!(start.elapsed() < Duration::from_secs(20), "the coordinator did not start:\n{}", proc.logs());
            std::thread::sleep(Duration::from_millis(20));
        }
    }
}

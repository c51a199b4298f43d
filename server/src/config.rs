//! The coordinator's configuration, in one place: [`ServeArgs`] are the flags of `cryofit serve`
//! (each with its environment variable, `CRYOFIT_MAX_BUDGET` for `--max-budget`, …), and
//! [`ServeArgs::settings`] adds the variables that have no flag — the tokens
//! (`CRYOFIT_CLIENT_TOKEN`, `CRYOFIT_WORKER_TOKEN`; secrets stay off the command line),
//! `CRYOFIT_LEASE_S`, `CRYOFIT_MAX_ATTEMPTS` and `CRYOFIT_BODY_LIMIT` — and checks them together
//! into [`Settings`]. Errors name the flag or the variable.

use std::time::Duration;

use secrecy::ExposeSecret as _;
use subtle::ConstantTimeEq as _;

use crate::coordinator::CoordinatorSettings;
use crate::fluids::{FluidLoader, embedded_fluids};
use crate::limits::Limits;

/// A setting that is wrong, with what to give instead.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{0}")]
pub struct ConfigError(pub String);

/// A secret that never shows in `Debug` output ([`secrecy::SecretString`]), compared in constant
/// time ([`subtle`]).
#[derive(Clone)]
pub struct Secret(secrecy::SecretString);

impl Secret {
    /// Wraps a secret.
    pub fn new(s: impl Into<String>) -> Self {
        Self(secrecy::SecretString::from(s.into()))
    }

    /// Compares in time independent of where the first difference is.
    pub fn matches(&self, other: &str) -> bool {
        self.0.expose_secret().as_bytes().ct_eq(other.as_bytes()).into()
    }

    /// True when both hold the same secret.
    pub fn same_as(&self, other: &Secret) -> bool {
        self.matches(other.0.expose_secret())
    }
}

impl std::fmt::Debug for Secret {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Secret(***)")
    }
}

/// The coordinator's settings.
#[derive(Clone)]
pub struct Settings {
    /// SQLite database: `sqlite://PATH` or a path; created if absent.
    pub database_url: String,
    /// Token of clients (submit, read, cancel).
    pub client_token: Option<Secret>,
    /// Token of workers (claim, heartbeat, result, read experiments).
    pub worker_token: Option<Secret>,
    /// Largest request body, bytes.
    pub body_limit: usize,
    /// Driver and lease settings.
    pub coordinator: CoordinatorSettings,
    /// How often the reaper looks for expired leases.
    pub reaper_interval: Duration,
    /// Fluid tables (for validating experiments and recording table hashes).
    pub fluids: FluidLoader,
    /// Ceilings on what one request can size.
    pub limits: Limits,
    /// Mark the dashboard's session cookie `Secure` (served behind TLS).
    pub secure_cookies: bool,
    /// How long a dashboard session lasts after signing in.
    pub session_ttl: Duration,
    /// How long the database lock lasts without renewal (another coordinator may take over a
    /// lock older than this whose holder it cannot see).
    pub lock_ttl: Duration,
}

impl std::fmt::Debug for Settings {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Settings")
            .field("database_url", &self.database_url)
            .field("client_token", &self.client_token)
            .field("worker_token", &self.worker_token)
            .field("body_limit", &self.body_limit)
            .field("coordinator", &self.coordinator)
            .field("reaper_interval", &self.reaper_interval)
            .field("limits", &self.limits)
            .field("secure_cookies", &self.secure_cookies)
            .field("session_ttl", &self.session_ttl)
            .field("lock_ttl", &self.lock_ttl)
            .finish_non_exhaustive()
    }
}

/// Default body limit: 16 MiB.
pub const DEFAULT_BODY_LIMIT: usize = 16 * 1024 * 1024;

/// Default lifetime of a dashboard session: 12 hours.
pub const DEFAULT_SESSION_TTL: Duration = Duration::from_secs(12 * 3600);

/// Default lifetime of the database lock without renewal: 15 s (renewed every 3 s).
pub const DEFAULT_LOCK_TTL: Duration = Duration::from_secs(15);

impl Settings {
    /// Defaults for a database, with the embedded fluid tables and no tokens.
    pub fn new(database_url: impl Into<String>) -> Self {
        Self {
            database_url: database_url.into(),
            client_token: None,
            worker_token: None,
            body_limit: DEFAULT_BODY_LIMIT,
            coordinator: CoordinatorSettings::default(),
            reaper_interval: Duration::from_secs(1),
            fluids: embedded_fluids(),
            limits: Limits::default(),
            secure_cookies: false,
            session_ttl: DEFAULT_SESSION_TTL,
            lock_ttl: DEFAULT_LOCK_TTL,
        }
    }

    /// Checks settings that depend on each other: the two tokens must differ (a worker token
    /// that is also the client token would let every worker submit and cancel).
    pub fn check(&self) -> Result<(), ConfigError> {
        if let (Some(c), Some(w)) = (&self.client_token, &self.worker_token)
            && c.same_as(w)
        {
            return Err(ConfigError(
                "CRYOFIT_CLIENT_TOKEN and CRYOFIT_WORKER_TOKEN are the same: give each role its own token \
                 (openssl rand -hex 32)"
                    .into(),
            ));
        }
        Ok(())
    }

    /// Layers the variables without a flag over these settings: `CRYOFIT_CLIENT_TOKEN`,
    /// `CRYOFIT_WORKER_TOKEN`, `CRYOFIT_LEASE_S` (lease length, s), `CRYOFIT_MAX_ATTEMPTS`,
    /// `CRYOFIT_BODY_LIMIT` (bytes), read with `var` (a blank value counts as unset).
    fn apply_environment(&mut self, var: &dyn Fn(&str) -> Option<String>) -> Result<(), ConfigError> {
        let var = |name: &str| var(name).filter(|v| !v.trim().is_empty());
        self.client_token = var("CRYOFIT_CLIENT_TOKEN").map(Secret::new);
        self.worker_token = var("CRYOFIT_WORKER_TOKEN").map(Secret::new);
        if let Some(v) = var("CRYOFIT_LEASE_S") {
            let secs: f64 = v
                .parse()
                .ok()
                .filter(|x: &f64| x.is_finite() && *x > 0.0 && *x < 86_400.0)
                .ok_or_else(|| ConfigError(format!("CRYOFIT_LEASE_S = {v}: give seconds in (0, 86400)")))?;
            self.coordinator.lease = Duration::from_secs_f64(secs);
            self.reaper_interval = Duration::from_secs_f64((secs / 4.0).clamp(0.05, 1.0));
        }
        if let Some(v) = var("CRYOFIT_MAX_ATTEMPTS") {
            self.coordinator.max_attempts = v
                .parse()
                .ok()
                .filter(|x| *x >= 1)
                .ok_or_else(|| ConfigError(format!("CRYOFIT_MAX_ATTEMPTS = {v}: give an integer ≥ 1")))?;
        }
        if let Some(v) = var("CRYOFIT_BODY_LIMIT") {
            self.body_limit = v
                .parse()
                .ok()
                .filter(|x| *x >= 1024)
                .ok_or_else(|| ConfigError(format!("CRYOFIT_BODY_LIMIT = {v}: give bytes ≥ 1024")))?;
        }
        self.check()
    }
}

/// The flags of `cryofit serve`.
#[derive(Debug, Clone, clap::Args)]
pub struct ServeArgs {
    /// Address to listen on (port 0 picks a free port; the chosen address is printed).
    #[arg(long, value_name = "ADDR", default_value = "127.0.0.1:8700")]
    pub bind: String,
    /// SQLite database (a path or sqlite://PATH); created if absent.
    #[arg(long, value_name = "URL", default_value = "cryofit.db")]
    pub database: String,
    /// Most evaluations of one calibration, all stages together.
    #[arg(long, value_name = "N", env = "CRYOFIT_MAX_BUDGET", default_value_t = Limits::DEFAULT_MAX_BUDGET)]
    pub max_budget: u64,
    /// Largest population, trajectories, walkers, points, levels, restarts or keep of a stage.
    #[arg(long, value_name = "N", env = "CRYOFIT_MAX_STAGE_SIZE", default_value_t = Limits::DEFAULT_MAX_STAGE_SIZE)]
    pub max_stage_size: u64,
    /// Largest estimated optimiser state of one calibration, bytes (it is written with every result).
    #[arg(long, value_name = "BYTES", env = "CRYOFIT_MAX_STATE_BYTES", default_value_t = Limits::DEFAULT_MAX_STATE_BYTES)]
    pub max_state_bytes: u64,
    /// Most values one evaluation records (probes and profiles up to the end of the data).
    #[arg(long, value_name = "N", env = "CRYOFIT_MAX_OUTPUT_POINTS", default_value_t = Limits::DEFAULT_MAX_OUTPUT_POINTS)]
    pub max_output_points: u64,
    /// Largest max_evaluation_s a calibration may ask for, s.
    #[arg(long, value_name = "SECS", env = "CRYOFIT_MAX_EVALUATION_S", default_value_t = Limits::DEFAULT_MAX_EVALUATION_S)]
    pub max_evaluation_s: f64,
    /// Mark the dashboard's session cookie Secure (set it when a TLS proxy serves the coordinator).
    #[arg(long, env = "CRYOFIT_SECURE_COOKIES")]
    pub secure_cookies: bool,
    /// Hours a dashboard session lasts after signing in.
    #[arg(long, value_name = "HOURS", env = "CRYOFIT_SESSION_HOURS", default_value_t = 12.0)]
    pub session_hours: f64,
}

impl ServeArgs {
    /// The settings of these flags and of the process environment, checked.
    pub fn settings(&self) -> Result<Settings, ConfigError> {
        self.settings_with(&|name| std::env::var(name).ok())
    }

    /// [`ServeArgs::settings`] with the environment read through `var`.
    pub fn settings_with(&self, var: &dyn Fn(&str) -> Option<String>) -> Result<Settings, ConfigError> {
        let mut settings = Settings::new(&self.database);
        settings.apply_environment(var)?;
        settings.limits = self.limits()?;
        settings.secure_cookies = self.secure_cookies;
        settings.session_ttl = self.session_ttl()?;
        Ok(settings)
    }

    /// The limits of the flags, checked.
    fn limits(&self) -> Result<Limits, ConfigError> {
        for (flag, v) in [
            ("--max-budget", self.max_budget),
            ("--max-stage-size", self.max_stage_size),
            ("--max-state-bytes", self.max_state_bytes),
            ("--max-output-points", self.max_output_points),
        ] {
            if v == 0 {
                return Err(ConfigError(format!("{flag} 0: give at least 1")));
            }
        }
        let e = self.max_evaluation_s;
        if !(e.is_finite() && e > 0.0) {
            return Err(ConfigError(format!("--max-evaluation-s {e}: give seconds > 0")));
        }
        Ok(Limits {
            max_budget: self.max_budget,
            max_stage_size: self.max_stage_size,
            max_state_bytes: self.max_state_bytes,
            max_output_points: self.max_output_points,
            max_evaluation_s: e,
        })
    }

    fn session_ttl(&self) -> Result<Duration, ConfigError> {
        let h = self.session_hours;
        if !(h.is_finite() && h > 0.0 && h <= 24.0 * 366.0) {
            return Err(ConfigError(format!("--session-hours {h}: give hours in (0, 8784]")));
        }
        Ok(Duration::from_secs_f64(h * 3600.0))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser as _;

    #[derive(Debug, clap::Parser)]
    struct Cli {
        #[command(flatten)]
        serve: ServeArgs,
    }

    fn args(flags: &[&str]) -> ServeArgs {
        let argv = std::iter::once("serve").chain(flags.iter().copied());
        Cli::try_parse_from(argv).expect("flags parse").serve
    }

    fn env<'a>(vars: &'a [(&'a str, &'a str)]) -> impl Fn(&str) -> Option<String> + 'a {
        move |name| vars.iter().find(|(k, _)| *k == name).map(|(_, v)| v.to_string())
    }

    #[test]
    fn identical_client_and_worker_tokens_are_refused() {
        let mut s = Settings::new("x.db");
        s.client_token = Some(Secret::new("same"));
        s.worker_token = Some(Secret::new("same"));
        assert!(s.check().unwrap_err().to_string().contains("are the same"));
        s.worker_token = Some(Secret::new("other"));
        assert!(s.check().is_ok());
        assert_eq!(format!("{:?}", s.client_token), "Some(Secret(***))");
    }

    #[test]
    fn flags_and_environment_make_one_set_of_settings() {
        let vars = [
            ("CRYOFIT_CLIENT_TOKEN", "c"),
            ("CRYOFIT_WORKER_TOKEN", "  "),
            ("CRYOFIT_LEASE_S", "2"),
            ("CRYOFIT_MAX_ATTEMPTS", "5"),
            ("CRYOFIT_BODY_LIMIT", "4096"),
        ];
        let a = args(&["--database", "d.db", "--max-budget", "12", "--session-hours", "1", "--secure-cookies"]);
        let s = a.settings_with(&env(&vars)).expect("settings");
        assert_eq!(s.database_url, "d.db");
        assert!(s.client_token.as_ref().is_some_and(|t| t.matches("c")));
        assert!(s.worker_token.is_none(), "a blank variable counts as unset");
        assert_eq!((s.coordinator.lease, s.reaper_interval), (Duration::from_secs(2), Duration::from_millis(500)));
        assert_eq!((s.coordinator.max_attempts, s.body_limit), (5, 4096));
        assert_eq!((s.limits.max_budget, s.secure_cookies), (12, true));
        assert_eq!(s.session_ttl, Duration::from_secs(3600));
        assert_eq!(a.bind, "127.0.0.1:8700");
    }

    #[test]
    fn wrong_settings_are_refused_naming_the_flag_or_variable() {
        let refused = |flags: &[&str], vars: &[(&str, &str)]| {
            args(flags).settings_with(&env(vars)).expect_err("refused").to_string()
        };
        assert_eq!(refused(&["--max-budget", "0"], &[]), "--max-budget 0: give at least 1");
        assert_eq!(refused(&["--max-evaluation-s=-1"], &[]), "--max-evaluation-s -1: give seconds > 0");
        assert_eq!(refused(&["--session-hours", "0"], &[]), "--session-hours 0: give hours in (0, 8784]");
        assert!(refused(&[], &[("CRYOFIT_LEASE_S", "0")]).starts_with("CRYOFIT_LEASE_S = 0:"));
        assert!(refused(&[], &[("CRYOFIT_MAX_ATTEMPTS", "x")]).starts_with("CRYOFIT_MAX_ATTEMPTS = x:"));
        assert!(refused(&[], &[("CRYOFIT_BODY_LIMIT", "10")]).starts_with("CRYOFIT_BODY_LIMIT = 10:"));
        let same = [("CRYOFIT_CLIENT_TOKEN", "t"), ("CRYOFIT_WORKER_TOKEN", "t")];
        assert!(refused(&[], &same).contains("are the same"));
    }
}

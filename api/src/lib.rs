//! The coordinator's REST contract (DESIGN.md §3.4): the JSON bodies of every route under
//! `/api/v1`, shared by the server, the worker and the CLI.
//!
//! Every request type rejects unknown fields. Numbers are JSON numbers, so NaN and ±∞ cannot be
//! expressed (a literal `NaN` or `1e999` is a malformed body). Times are Unix milliseconds.
//!
//! # Calibrations refer to stored experiments
//! `POST /calibrations` takes [`CreateCalibration`]: the calibration file's content
//! ([`cryofit_calib::config::CalibrationSpec`]) except that `experiments` is a list of ids of
//! experiments stored with `POST /experiments`, instead of file paths.

#![warn(missing_docs)]

use std::collections::BTreeMap;

use cryofit_calib::config::{ParameterSpec, StageSpec, WeightSpec};
use serde::{Deserialize, Serialize};
use utoipa::{IntoParams, ToSchema};

/// Version of the model code a calibration runs with: the workspace version shared by the solver,
/// the inference engine and this contract. Workers built from another version are refused jobs.
pub const SOLVER_VERSION: &str = env!("CARGO_PKG_VERSION");

/// Maximum page size of the history endpoints; a larger `limit` is clamped to it.
pub const MAX_PAGE: i64 = 1000;

/// Default page size of the history endpoints.
pub const DEFAULT_PAGE: i64 = 100;

/// Hash of a fluid table's bytes (64-bit FNV-1a, 16 hex digits): what a calibration and a worker
/// compare to make sure they run on the same property tables.
pub fn fluid_hash(bytes: &[u8]) -> String {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for &b in bytes {
        h ^= u64::from(b);
        h = h.wrapping_mul(0x0100_0000_01b3);
    }
    format!("{h:016x}")
}

/// The body of every error response: `{"error": {"code", "message", "field"?}}`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct ErrorBody {
    /// The error.
    pub error: ErrorDetail,
}

/// What went wrong, for people (`message`) and programs (`code`, `field`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct ErrorDetail {
    /// Stable machine-readable code: `bad_request`, `invalid_json`, `validation`, `not_found`,
    /// `unauthorized`, `forbidden`, `payload_too_large`, `conflict`, `internal`.
    pub code: String,
    /// One line saying what is wrong and what to change.
    pub message: String,
    /// The offending field as a path (`stages[0].budget`), when one field is at fault.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub field: Option<String>,
}

/// `{"id": …}`: the answer to a creation.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
pub struct Created {
    /// Id of the new resource.
    pub id: i64,
}

/// A page of a list: `{items, next_offset}`; `next_offset` is absent on the last page.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct Page<T> {
    /// The items of this page.
    pub items: Vec<T>,
    /// Offset of the next page, `null` when there is none.
    pub next_offset: Option<i64>,
}

/// `?limit=&offset=` of list endpoints, with optional filters.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize, IntoParams)]
#[serde(deny_unknown_fields)]
pub struct PageQuery {
    /// Page size; clamped to [1, [`MAX_PAGE`]], default [`DEFAULT_PAGE`].
    #[serde(default)]
    pub limit: Option<i64>,
    /// Number of items to skip (≥ 0).
    #[serde(default)]
    pub offset: Option<i64>,
    /// Only items of this status (`ok`, `failed`, `pending`, `stale`).
    #[serde(default)]
    pub status: Option<String>,
    /// Only items of this pipeline stage (parameter sets).
    #[serde(default)]
    pub stage: Option<i64>,
    /// Only results of this experiment.
    #[serde(default)]
    pub experiment_id: Option<i64>,
}

// ---------------------------------------------------------------------------------------------
// experiments

/// `POST /experiments`: a case file and its measured time series, as text.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct CreateExperiment {
    /// Name used in reports (not empty).
    pub name: String,
    /// The case file (TOML, DESIGN.md §3.3).
    pub case: String,
    /// The measurements (long-format CSV, DESIGN.md §3.2).
    pub data: String,
}

/// An experiment as listed (without its texts).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct ExperimentSummary {
    /// Id.
    pub id: i64,
    /// Name.
    pub name: String,
    /// Fluid of the case.
    pub fluid: String,
    /// Creation time, Unix ms.
    pub created: i64,
}

/// An experiment with its case and data texts (`GET /experiments/{id}`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct Experiment {
    /// Id.
    pub id: i64,
    /// Name.
    pub name: String,
    /// Fluid of the case.
    pub fluid: String,
    /// The case file text.
    pub case: String,
    /// The data file text.
    pub data: String,
    /// Creation time, Unix ms.
    pub created: i64,
}

// ---------------------------------------------------------------------------------------------
// calibrations

/// `POST /calibrations`: the calibration file's content with `experiments` given as ids.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct CreateCalibration {
    /// Name (not empty).
    pub name: String,
    /// Free text.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub description: Option<String>,
    /// Seed of every stage's random stream: the same seed gives the same calibration.
    #[serde(default)]
    pub seed: u64,
    /// Ids of stored experiments to fit (at least one, each once).
    pub experiments: Vec<i64>,
    /// Free parameters with optional bounds and scale: registry names, or case fields
    /// (`case.<path>`, bounds required; `experiments`: names of experiments that each get a copy);
    /// `start`: where the calibration starts, within the bounds.
    #[schema(value_type = Vec<Object>)]
    pub parameters: Vec<ParameterSpec>,
    /// Other parameters held at given values: registry names, or case fields set in every
    /// experiment's case (`case.<path>`, `"case.pipe.cells": 120`) or in one's
    /// (`case.<path>@<experiment name>`).
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub fixed: BTreeMap<String, f64>,
    /// Weight η and noise σ per quantity: `{"wall_temperature_k": {"weight": 1, "sigma": 1}}`.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    #[schema(value_type = Object)]
    pub weights: BTreeMap<String, WeightSpec>,
    /// Stages in order, each `{"algorithm", "budget", …options}`.
    #[schema(value_type = Vec<Object>)]
    pub stages: Vec<StageSpec>,
    /// Wall-clock limit of one simulation, s (default 120): a longer run is a failed evaluation.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_evaluation_s: Option<f64>,
}

/// Lifecycle of a calibration.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "lowercase")]
pub enum CalibrationStatus {
    /// Stored, not yet handing out jobs.
    Queued,
    /// Handing out jobs.
    Running,
    /// Every stage finished.
    Completed,
    /// Stopped on an error (see `error`).
    Failed,
    /// Cancelled by a client.
    Cancelled,
}

impl CalibrationStatus {
    /// The lowercase name stored and sent.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Queued => "queued",
            Self::Running => "running",
            Self::Completed => "completed",
            Self::Failed => "failed",
            Self::Cancelled => "cancelled",
        }
    }

    /// Parses the lowercase name.
    pub fn parse(s: &str) -> Option<Self> {
        Some(match s {
            "queued" => Self::Queued,
            "running" => Self::Running,
            "completed" => Self::Completed,
            "failed" => Self::Failed,
            "cancelled" => Self::Cancelled,
            _ => return None,
        })
    }

    /// True for the states a calibration never leaves.
    pub fn is_final(self) -> bool {
        matches!(self, Self::Completed | Self::Failed | Self::Cancelled)
    }
}

/// A calibration's state and progress (`GET /calibrations/{id}`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct Calibration {
    /// Id.
    pub id: i64,
    /// Name.
    pub name: String,
    /// Lifecycle state.
    pub status: CalibrationStatus,
    /// Parameter sets evaluated (told to the optimiser), failed ones included.
    pub evaluations: i64,
    /// Of those, how many failed.
    pub failed_evaluations: i64,
    /// Total budget of all stages.
    pub budget: i64,
    /// Index of the running stage.
    pub stage: i64,
    /// Best cost so far.
    pub best_cost: Option<f64>,
    /// Free parameters of the best point so far, by name.
    pub best_parameters: Option<BTreeMap<String, f64>>,
    /// Experiment ids.
    pub experiments: Vec<i64>,
    /// Model version the calibration runs with.
    pub solver_version: String,
    /// Fluid-table hash per fluid the experiments use.
    pub fluid_hashes: BTreeMap<String, String>,
    /// Why the calibration failed.
    pub error: Option<String>,
    /// The calibration as submitted.
    #[schema(value_type = Object)]
    pub spec: serde_json::Value,
    /// Reports of the finished stages (sensitivity rankings, variance, posterior summaries).
    #[schema(value_type = Vec<Object>)]
    pub stages: Vec<serde_json::Value>,
    /// Creation time, Unix ms.
    pub created: i64,
    /// Last change, Unix ms.
    pub updated: i64,
}

/// A parameter set of a calibration's history.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct ParameterSetItem {
    /// Id (the coordinator's).
    pub id: i64,
    /// Calibration id.
    pub calibration_id: i64,
    /// The optimiser's job id (0, 1, 2, … within the calibration).
    pub job: i64,
    /// Stage that asked for it.
    pub stage: i64,
    /// Free-parameter values by name.
    pub parameters: BTreeMap<String, f64>,
    /// `pending`, `ok` or `failed`.
    pub status: String,
    /// Summed cost over the experiments (when `ok`).
    pub cost: Option<f64>,
    /// Why it failed.
    pub reason: Option<String>,
    /// Creation time, Unix ms.
    pub created: i64,
}

/// One reported result of one (parameter set, experiment) job.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct ResultItem {
    /// Id of the result record.
    pub id: i64,
    /// Parameter set.
    pub parameter_set_id: i64,
    /// Job.
    pub job_id: i64,
    /// Experiment.
    pub experiment_id: i64,
    /// `ok`, `failed` or `stale` (a late result of an expired lease, not counted).
    pub status: String,
    /// Cost of this experiment.
    pub cost: Option<f64>,
    /// Why it failed.
    pub reason: Option<String>,
    /// Worker that reported it.
    pub worker: Option<String>,
    /// Wall time of the evaluation, s.
    pub duration_s: Option<f64>,
    /// Per-series cost breakdown as reported.
    #[schema(value_type = Object)]
    pub breakdown: Option<serde_json::Value>,
    /// Report time, Unix ms.
    pub created: i64,
}

// ---------------------------------------------------------------------------------------------
// workers

/// `POST /jobs/claim`: lease up to `max_jobs` jobs.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct ClaimRequest {
    /// Worker name (unique per process, e.g. host:pid).
    pub worker: String,
    /// Simulations the worker runs at once.
    pub slots: u32,
    /// Jobs wanted now (0–1000).
    pub max_jobs: u32,
    /// The worker's [`SOLVER_VERSION`].
    pub solver_version: String,
    /// Fluid-table hash per fluid the worker can load.
    pub fluid_hashes: BTreeMap<String, String>,
}

/// Leased jobs, what the worker needs to run them, and the calibrations it was refused.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct ClaimResponse {
    /// The jobs leased.
    pub jobs: Vec<LeasedJob>,
    /// Settings of the calibrations of these jobs.
    pub calibrations: Vec<JobContext>,
    /// Calibrations with work whose jobs this worker may not run, and why.
    pub refused: Vec<Refusal>,
}

/// One leased job: one experiment at one parameter set.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct LeasedJob {
    /// Job id.
    pub id: i64,
    /// Lease id to quote in heartbeats and the result.
    pub lease_id: String,
    /// Seconds until the lease expires without a heartbeat.
    pub lease_s: f64,
    /// Calibration.
    pub calibration_id: i64,
    /// Parameter set.
    pub parameter_set_id: i64,
    /// Experiment to run (`GET /experiments/{id}`).
    pub experiment_id: i64,
    /// Free-parameter values by name.
    pub parameters: BTreeMap<String, f64>,
}

/// A calibration's evaluation settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct JobContext {
    /// Calibration.
    pub calibration_id: i64,
    /// Fixed parameter values (registry names and case fields, as in the calibration's `fixed`).
    pub fixed: BTreeMap<String, f64>,
    /// Weights of the cost.
    #[schema(value_type = Object)]
    pub weights: BTreeMap<String, WeightSpec>,
    /// Wall-clock limit of one simulation, s.
    pub max_evaluation_s: f64,
}

/// A calibration whose jobs a worker may not run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct Refusal {
    /// Calibration.
    pub calibration_id: i64,
    /// Why (solver version or fluid table differs).
    pub reason: String,
}

/// `POST /jobs/{id}/heartbeat`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct HeartbeatRequest {
    /// The lease id of the claim.
    pub lease_id: String,
}

/// Answer to a heartbeat.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct HeartbeatResponse {
    /// Seconds until the extended lease expires.
    pub lease_s: f64,
    /// True when the calibration was cancelled: the worker may drop the job.
    pub cancelled: bool,
}

/// How one evaluation ended.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(tag = "status", rename_all = "lowercase", deny_unknown_fields)]
pub enum JobOutcome {
    /// A finite cost ≥ 0.
    Ok {
        /// The cost of this experiment.
        cost: f64,
    },
    /// The simulation failed (diverged, timed out, …).
    Failed {
        /// Why.
        reason: String,
    },
}

/// Per-series part of a cost.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct SeriesCost {
    /// Station name.
    pub station: String,
    /// Quantity.
    pub quantity: String,
    /// Weighted sum of squares of this series.
    pub cost: f64,
    /// RMS model − data.
    pub rms: f64,
    /// Data points.
    pub points: u64,
}

/// `POST /jobs/{id}/result`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct ResultRequest {
    /// The lease id of the claim; a result with an old lease id is recorded as stale.
    pub lease_id: String,
    /// The outcome.
    pub outcome: JobOutcome,
    /// Wall time of the evaluation, s.
    #[serde(default)]
    pub duration_s: Option<f64>,
    /// Per-series breakdown of the cost.
    #[serde(default)]
    pub breakdown: Option<Vec<SeriesCost>>,
    /// The worker that ran it.
    #[serde(default)]
    pub worker: Option<String>,
}

/// Largest number of results in one `POST /jobs/results`.
pub const MAX_RESULT_BATCH: usize = 1000;

/// One job's result inside a [`ResultBatch`]: [`ResultRequest`] with the job id.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct JobResult {
    /// The job.
    pub job_id: i64,
    /// The lease id of the claim; a result with an old lease id is recorded as stale.
    pub lease_id: String,
    /// The outcome.
    pub outcome: JobOutcome,
    /// Wall time of the evaluation, s.
    #[serde(default)]
    pub duration_s: Option<f64>,
    /// Per-series breakdown of the cost.
    #[serde(default)]
    pub breakdown: Option<Vec<SeriesCost>>,
    /// The worker that ran it.
    #[serde(default)]
    pub worker: Option<String>,
}

/// `POST /jobs/results`: results of several jobs, recorded (and told to the optimiser) in one
/// transaction. Either every result is recorded or, on a 4xx answer, none is.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct ResultBatch {
    /// 1 to [`MAX_RESULT_BATCH`] results, each job at most once.
    pub results: Vec<JobResult>,
}

/// Answer to a [`ResultBatch`]: one [`ResultResponse`] per result, in order.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct ResultBatchResponse {
    /// Per result, in the order sent.
    pub results: Vec<ResultResponse>,
}

/// Answer to a result.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct ResultResponse {
    /// `ok`, `failed`, or `stale` (not counted).
    pub status: String,
    /// True when the result was counted.
    pub counted: bool,
}

/// `GET /healthz`: 200 with `status: "ok"`, or 503 with `status: "unhealthy"` and the reason (for
/// example a database that cannot be written).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct Health {
    /// `ok` or `unhealthy`.
    pub status: String,
    /// Server version.
    pub version: String,
    /// Why the coordinator is unhealthy.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reason: Option<String>,
}

/// Server-wide ceilings on what one request can size, set at `cryofit serve` (flags named beside
/// each field) and listed in the OpenAPI document. A request over one of them is refused with 422
/// naming the field and the limit.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct Limits {
    /// Evaluations of one calibration, all stages together (`--max-budget`).
    pub max_budget: u64,
    /// Population, trajectories, walkers, grid points, levels, restarts or `keep` of one stage
    /// (`--max-stage-size`).
    pub max_stage_size: u64,
    /// Estimated size of one calibration's optimiser state as stored (JSON), bytes
    /// (`--max-state-bytes`); the state is written with every result.
    pub max_state_bytes: u64,
    /// Values one evaluation records (probes at every station and whole-line profiles, up to
    /// the end of the data: `end / output_interval_s × stations × 10` and
    /// `end / profile_interval_s × cells × 8`) (`--max-output-points`).
    pub max_output_points: u64,
    /// Largest `max_evaluation_s` of a calibration, s (`--max-evaluation-s`).
    pub max_evaluation_s: f64,
}

impl Limits {
    /// Default `--max-budget`.
    pub const DEFAULT_MAX_BUDGET: u64 = 1_000_000;
    /// Default `--max-stage-size`.
    pub const DEFAULT_MAX_STAGE_SIZE: u64 = 10_000;
    /// Default `--max-state-bytes` (32 MiB).
    pub const DEFAULT_MAX_STATE_BYTES: u64 = 32 * 1024 * 1024;
    /// Default `--max-output-points`.
    pub const DEFAULT_MAX_OUTPUT_POINTS: u64 = 250_000;
    /// Default `--max-evaluation-s`.
    pub const DEFAULT_MAX_EVALUATION_S: f64 = 600.0;
}

impl Default for Limits {
    fn default() -> Self {
        Self {
            max_budget: Self::DEFAULT_MAX_BUDGET,
            max_stage_size: Self::DEFAULT_MAX_STAGE_SIZE,
            max_state_bytes: Self::DEFAULT_MAX_STATE_BYTES,
            max_output_points: Self::DEFAULT_MAX_OUTPUT_POINTS,
            max_evaluation_s: Self::DEFAULT_MAX_EVALUATION_S,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fnv_hash_is_stable() {
        assert_eq!(fluid_hash(b""), "cbf29ce484222325");
        assert_eq!(fluid_hash(b"a"), "af63dc4c8601ec8c");
    }

    #[test]
    fn requests_reject_unknown_fields_and_non_finite_numbers() {
        let e = serde_json::from_str::<CreateExperiment>(r#"{"name":"a","case":"","data":"","x":1}"#).unwrap_err();
        assert!(e.to_string().contains("unknown field `x`"), "{e}");
        assert!(serde_json::from_str::<JobOutcome>(r#"{"status":"ok","cost":NaN}"#).is_err());
        assert!(serde_json::from_str::<JobOutcome>(r#"{"status":"ok","cost":1e999}"#).is_err());
        let o: JobOutcome = serde_json::from_str(r#"{"status":"failed","reason":"x"}"#).unwrap();
        assert_eq!(o, JobOutcome::Failed { reason: "x".into() });
    }
}

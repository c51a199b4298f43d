//! The OpenAPI 3.1 document: the routes' `#[utoipa::path]` annotations, collected as the routes
//! are declared ([`super::api_routes`]), in a frame of the `api` types, the bearer scheme and this
//! coordinator's limits.

use cryofit_api as api;
use utoipa::OpenApi;

#[derive(OpenApi)]
#[openapi(
    info(title = "cryofit coordinator", description = "Experiments, calibrations, history and worker jobs."),
    components(schemas(
        api::ErrorBody,
        api::ErrorDetail,
        api::Created,
        api::CreateExperiment,
        api::Experiment,
        api::ExperimentSummary,
        api::CreateCalibration,
        api::Calibration,
        api::CalibrationStatus,
        api::ParameterSetItem,
        api::ResultItem,
        api::ClaimRequest,
        api::ClaimResponse,
        api::LeasedJob,
        api::JobContext,
        api::Refusal,
        api::HeartbeatRequest,
        api::HeartbeatResponse,
        api::ResultRequest,
        api::ResultResponse,
        api::JobResult,
        api::ResultBatch,
        api::ResultBatchResponse,
        api::JobOutcome,
        api::SeriesCost,
        api::Health,
        api::Limits,
    )),
    modifiers(&Security)
)]
struct Frame;

struct Security;

impl utoipa::Modify for Security {
    fn modify(&self, openapi: &mut utoipa::openapi::OpenApi) {
        use utoipa::openapi::security::{HttpAuthScheme, HttpBuilder, SecurityScheme};
        let components = openapi.components.get_or_insert_with(Default::default);
        components.add_security_scheme(
            "bearer",
            SecurityScheme::Http(HttpBuilder::new().scheme(HttpAuthScheme::Bearer).build()),
        );
        openapi.security =
            Some(vec![utoipa::openapi::security::SecurityRequirement::new("bearer", Vec::<String>::new())]);
    }
}

/// The document without paths: info, the `api` schemas, the bearer scheme.
pub(super) fn frame() -> utoipa::openapi::OpenApi {
    Frame::openapi()
}

/// Adds this coordinator's [`api::Limits`] to the document: in the description, and as the
/// extension `x-cryofit-limits` of `info` (the same object as the `Limits` schema).
pub(super) fn with_limits(mut doc: utoipa::openapi::OpenApi, limits: &api::Limits) -> utoipa::openapi::OpenApi {
    let text = format!(
        "Experiments, calibrations, history and worker jobs.\n\nLimits of this coordinator (a request over one \
         is refused with 422 naming the field): at most {} evaluations per calibration (--max-budget); stage \
         population, trajectories, walkers, points, levels, restarts and keep at most {} (--max-stage-size); \
         optimiser state at most {} bytes (--max-state-bytes); at most {} recorded values per evaluation \
         (--max-output-points); max_evaluation_s at most {} s (--max-evaluation-s).",
        limits.max_budget,
        limits.max_stage_size,
        limits.max_state_bytes,
        limits.max_output_points,
        limits.max_evaluation_s
    );
    doc.info.description = Some(text);
    if let Ok(value) = serde_json::to_value(limits) {
        let ext = utoipa::openapi::extensions::ExtensionsBuilder::new().add("x-cryofit-limits", value).build();
        doc.info.extensions.get_or_insert_with(Default::default).merge(ext);
    }
    doc
}

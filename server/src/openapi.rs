//! The OpenAPI 3.1 document, generated from the route annotations and the `api` types.

use cryofit_api as api;
use utoipa::OpenApi;

use crate::routes;

#[derive(OpenApi)]
#[openapi(
    info(title = "cryofit coordinator", description = "Experiments, calibrations, history and worker jobs."),
    paths(
        routes::create_experiment,
        routes::list_experiments,
        routes::get_experiment,
        routes::create_calibration,
        routes::list_calibrations,
        routes::get_calibration,
        routes::cancel_calibration,
        routes::parameter_sets,
        routes::results,
        routes::claim,
        routes::heartbeat,
        routes::result,
        routes::results_batch,
    ),
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
    )),
    modifiers(&Security)
)]
struct Doc;

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

/// The document.
pub fn document() -> utoipa::openapi::OpenApi {
    Doc::openapi()
}

//! HTTP client of the coordinator's REST API (used by the worker loop and the CLI).
//!
//! Transport failures, 429 and 5xx answers are retried with exponential backoff and jitter for up to
//! [`Client::with_retry_for`] (the coordinator may be restarting); 4xx answers are returned at once
//! as [`ClientError::Api`] with the server's code, message and field.

use std::time::Duration;

use cryofit_api as api;
use rand::Rng;
use reqwest::{Method, StatusCode};
use serde::Serialize;
use serde::de::DeserializeOwned;

/// Why a request failed.
#[derive(Debug, Clone, thiserror::Error)]
#[non_exhaustive]
pub enum ClientError {
    /// The coordinator answered with an error.
    #[error("{status}: {message}{}", field.as_ref().map(|f| format!(" (field `{f}`)")).unwrap_or_default())]
    Api {
        /// HTTP status.
        status: u16,
        /// Error code.
        code: String,
        /// Message.
        message: String,
        /// Offending field.
        field: Option<String>,
    },
    /// The coordinator could not be reached (after retrying).
    #[error("cannot reach the coordinator at {url}: {message}")]
    Transport {
        /// URL.
        url: String,
        /// What failed.
        message: String,
    },
}

impl ClientError {
    /// The HTTP status of an API error.
    pub fn status(&self) -> Option<u16> {
        match self {
            Self::Api { status, .. } => Some(*status),
            Self::Transport { .. } => None,
        }
    }
}

/// A coordinator client.
#[derive(Debug, Clone)]
pub struct Client {
    http: reqwest::Client,
    base: String,
    token: Option<String>,
    retry_for: Duration,
}

/// The body of a history request in CSV or JSON.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    /// `{items, next_offset}`.
    Json,
    /// CSV text.
    Csv,
}

impl Client {
    /// A client of the coordinator at `base` (`http://host:port`), with an optional bearer token.
    pub fn new(base: &str, token: Option<String>) -> Result<Self, ClientError> {
        let http = reqwest::Client::builder()
            .connect_timeout(Duration::from_secs(5))
            .timeout(Duration::from_secs(60))
            .build()
            .map_err(|e| ClientError::Transport { url: base.to_string(), message: e.to_string() })?;
        let base = base.trim_end_matches('/').to_string();
        if !(base.starts_with("http://") || base.starts_with("https://")) {
            return Err(ClientError::Transport {
                url: base,
                message: "the coordinator URL must start with http:// or https://".into(),
            });
        }
        Ok(Self { http, base, token, retry_for: Duration::from_secs(60) })
    }

    /// How long transport failures and 5xx answers are retried (default 60 s).
    pub fn with_retry_for(mut self, d: Duration) -> Self {
        self.retry_for = d;
        self
    }

    /// The base URL.
    pub fn base(&self) -> &str {
        &self.base
    }

    async fn raw(
        &self,
        method: Method,
        path: &str,
        body: Option<&(impl Serialize + ?Sized)>,
        accept: Option<&str>,
    ) -> Result<(StatusCode, String), ClientError> {
        let url = format!("{}/api/v1{path}", self.base);
        let started = std::time::Instant::now();
        let mut delay = Duration::from_millis(100);
        loop {
            let mut req = self.http.request(method.clone(), &url);
            if let Some(t) = &self.token {
                req = req.bearer_auth(t);
            }
            if let Some(b) = body {
                req = req.json(b);
            }
            if let Some(a) = accept {
                req = req.header(reqwest::header::ACCEPT, a);
            }
            let attempt = async {
                let resp = req.send().await?;
                let status = resp.status();
                let text = resp.text().await?;
                Ok::<_, reqwest::Error>((status, text))
            }
            .await;
            let retry_reason = match attempt {
                // 429: the coordinator (or a proxy) asks to come back later, like a 5xx
                Ok((status, text)) if !status.is_server_error() && status != StatusCode::TOO_MANY_REQUESTS => {
                    return Ok((status, text));
                }
                Ok((status, text)) => format!("{status}: {text}"),
                Err(e) => e.to_string(),
            };
            if started.elapsed() + delay > self.retry_for {
                return Err(ClientError::Transport { url, message: retry_reason });
            }
            tracing::warn!(%url, error = %retry_reason, retry_in_ms = delay.as_millis() as u64, "coordinator away; retrying");
            let jitter = rand::thread_rng().gen_range(0.5..1.5);
            tokio::time::sleep(delay.mul_f64(jitter)).await;
            delay = (delay * 2).min(Duration::from_secs(5));
        }
    }

    async fn call<T: DeserializeOwned>(
        &self,
        method: Method,
        path: &str,
        body: Option<&(impl Serialize + ?Sized)>,
    ) -> Result<T, ClientError> {
        let (status, text) = self.raw(method, path, body, None).await?;
        parse(status, &text)
    }

    /// `POST /experiments`.
    pub async fn create_experiment(&self, e: &api::CreateExperiment) -> Result<api::Created, ClientError> {
        self.call(Method::POST, "/experiments", Some(e)).await
    }

    /// `GET /experiments/{id}`.
    pub async fn experiment(&self, id: i64) -> Result<api::Experiment, ClientError> {
        self.call(Method::GET, &format!("/experiments/{id}"), None::<&()>).await
    }

    /// Every stored experiment, without its texts (all pages).
    pub async fn experiments(&self) -> Result<Vec<api::ExperimentSummary>, ClientError> {
        self.pages(|offset| format!("/experiments?limit=1000&offset={offset}")).await
    }

    /// Every calibration (all pages).
    pub async fn calibrations(&self) -> Result<Vec<api::Calibration>, ClientError> {
        self.pages(|offset| format!("/calibrations?limit=1000&offset={offset}")).await
    }

    async fn pages<T: DeserializeOwned>(&self, path: impl Fn(i64) -> String) -> Result<Vec<T>, ClientError> {
        let mut out = Vec::new();
        let mut offset = 0;
        loop {
            let page: api::Page<T> = self.call(Method::GET, &path(offset), None::<&()>).await?;
            out.extend(page.items);
            match page.next_offset {
                Some(n) => offset = n,
                None => return Ok(out),
            }
        }
    }

    /// `POST /calibrations`.
    pub async fn create_calibration(&self, c: &api::CreateCalibration) -> Result<api::Created, ClientError> {
        self.call(Method::POST, "/calibrations", Some(c)).await
    }

    /// `GET /calibrations/{id}`.
    pub async fn calibration(&self, id: i64) -> Result<api::Calibration, ClientError> {
        self.call(Method::GET, &format!("/calibrations/{id}"), None::<&()>).await
    }

    /// `POST /calibrations/{id}/cancel`.
    pub async fn cancel(&self, id: i64) -> Result<api::Calibration, ClientError> {
        self.call(Method::POST, &format!("/calibrations/{id}/cancel"), None::<&()>).await
    }

    /// Every parameter set of a calibration (all pages).
    pub async fn parameter_sets(&self, id: i64) -> Result<Vec<api::ParameterSetItem>, ClientError> {
        let mut out = Vec::new();
        let mut offset = 0;
        loop {
            let page: api::Page<api::ParameterSetItem> = self
                .call(
                    Method::GET,
                    &format!("/calibrations/{id}/parameter-sets?limit=1000&offset={offset}"),
                    None::<&()>,
                )
                .await?;
            out.extend(page.items);
            match page.next_offset {
                Some(n) => offset = n,
                None => return Ok(out),
            }
        }
    }

    /// One page of a calibration's results, as JSON text or CSV.
    pub async fn results_page(&self, id: i64, limit: i64, offset: i64, format: Format) -> Result<String, ClientError> {
        let accept = match format {
            Format::Json => "application/json",
            Format::Csv => "text/csv",
        };
        let (status, text) = self
            .raw(
                Method::GET,
                &format!("/calibrations/{id}/results?limit={limit}&offset={offset}"),
                None::<&()>,
                Some(accept),
            )
            .await?;
        if status.is_success() { Ok(text) } else { Err(api_error(status, &text)) }
    }

    /// Every result of a calibration (all pages).
    pub async fn results(&self, id: i64) -> Result<Vec<api::ResultItem>, ClientError> {
        let mut out = Vec::new();
        let mut offset = 0;
        loop {
            let page: api::Page<api::ResultItem> = self
                .call(Method::GET, &format!("/calibrations/{id}/results?limit=1000&offset={offset}"), None::<&()>)
                .await?;
            out.extend(page.items);
            match page.next_offset {
                Some(n) => offset = n,
                None => return Ok(out),
            }
        }
    }

    /// `POST /jobs/claim`.
    pub async fn claim(&self, req: &api::ClaimRequest) -> Result<api::ClaimResponse, ClientError> {
        self.call(Method::POST, "/jobs/claim", Some(req)).await
    }

    /// `POST /jobs/{id}/heartbeat`.
    pub async fn heartbeat(&self, job: i64, lease_id: &str) -> Result<api::HeartbeatResponse, ClientError> {
        let body = api::HeartbeatRequest { lease_id: lease_id.to_string() };
        self.call(Method::POST, &format!("/jobs/{job}/heartbeat"), Some(&body)).await
    }

    /// `POST /jobs/results`: several results in one request and one transaction.
    pub async fn report(&self, batch: &api::ResultBatch) -> Result<api::ResultBatchResponse, ClientError> {
        self.call(Method::POST, "/jobs/results", Some(batch)).await
    }

    /// `POST /jobs/{id}/result`.
    pub async fn result(&self, job: i64, req: &api::ResultRequest) -> Result<api::ResultResponse, ClientError> {
        self.call(Method::POST, &format!("/jobs/{job}/result"), Some(req)).await
    }
}

fn api_error(status: StatusCode, text: &str) -> ClientError {
    match serde_json::from_str::<api::ErrorBody>(text) {
        Ok(b) => ClientError::Api {
            status: status.as_u16(),
            code: b.error.code,
            message: b.error.message,
            field: b.error.field,
        },
        Err(_) => ClientError::Api {
            status: status.as_u16(),
            code: "http".into(),
            message: text.chars().take(300).collect(),
            field: None,
        },
    }
}

fn parse<T: DeserializeOwned>(status: StatusCode, text: &str) -> Result<T, ClientError> {
    if !status.is_success() {
        return Err(api_error(status, text));
    }
    serde_json::from_str(text).map_err(|e| ClientError::Api {
        status: status.as_u16(),
        code: "unexpected_body".into(),
        message: format!("the coordinator's answer does not parse: {e}"),
        field: None,
    })
}

//! A calibration's history as CSV (the `csv` crate, quoting only fields that need it, records
//! ended by `\n`): the parameter sets with a column per parameter, and the results.

use axum::http::{HeaderMap, header};
use axum::response::{IntoResponse, Response};
use cryofit_api as api;

use super::error::{ApiError, ApiResult};

/// True when the request asks for CSV (`Accept: text/csv`).
pub(crate) fn wanted(headers: &HeaderMap) -> bool {
    headers.get(header::ACCEPT).and_then(|v| v.to_str().ok()).is_some_and(|v| v.contains("text/csv"))
}

/// A CSV answer.
pub(crate) fn response(text: String) -> Response {
    ([(header::CONTENT_TYPE, "text/csv; charset=utf-8")], text).into_response()
}

fn opt<T: std::fmt::Display>(v: Option<T>) -> String {
    v.map_or_else(String::new, |x| x.to_string())
}

/// Writes records to a string.
fn write<I, R>(records: I) -> ApiResult<String>
where
    I: IntoIterator<Item = R>,
    R: IntoIterator,
    R::Item: AsRef<[u8]>,
{
    let failed = |e: &dyn std::fmt::Display| ApiError::internal(format!("writing CSV: {e}"));
    let mut w = ::csv::WriterBuilder::new()
        .quote_style(::csv::QuoteStyle::Necessary)
        .terminator(::csv::Terminator::Any(b'\n'))
        .from_writer(Vec::new());
    for r in records {
        w.write_record(r).map_err(|e| failed(&e))?;
    }
    let bytes = w.into_inner().map_err(|e| failed(&e))?;
    String::from_utf8(bytes).map_err(|e| failed(&e))
}

/// Parameter sets as CSV: `id,job,stage,status,cost,reason` and a column per parameter.
pub(crate) fn parameter_sets(items: &[api::ParameterSetItem]) -> ApiResult<String> {
    let names: Vec<&String> =
        items.iter().flat_map(|i| i.parameters.keys()).collect::<std::collections::BTreeSet<_>>().into_iter().collect();
    let head = ["id", "job", "stage", "status", "cost", "reason"].map(String::from).into_iter();
    let header: Vec<String> = head.chain(names.iter().map(|n| n.to_string())).collect();
    let rows = items.iter().map(|i| {
        let mut r = vec![
            i.id.to_string(),
            i.job.to_string(),
            i.stage.to_string(),
            i.status.clone(),
            opt(i.cost),
            i.reason.clone().unwrap_or_default(),
        ];
        r.extend(names.iter().map(|n| opt(i.parameters.get(*n))));
        r
    });
    write(std::iter::once(header).chain(rows))
}

/// Results as CSV.
pub(crate) fn results(items: &[api::ResultItem]) -> ApiResult<String> {
    let header =
        ["id", "parameter_set_id", "job_id", "experiment_id", "status", "cost", "reason", "worker", "duration_s"]
            .map(String::from)
            .to_vec();
    let rows = items.iter().map(|i| {
        vec![
            i.id.to_string(),
            i.parameter_set_id.to_string(),
            i.job_id.to_string(),
            i.experiment_id.to_string(),
            i.status.clone(),
            opt(i.cost),
            i.reason.clone().unwrap_or_default(),
            i.worker.clone().unwrap_or_default(),
            opt(i.duration_s),
        ]
    });
    write(std::iter::once(header).chain(rows))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The quoting of the hand-written writer these replace: a field is quoted when it holds a
    /// comma, a quote, CR or LF, and its quotes are doubled.
    fn hand_quoted(s: &str) -> String {
        if s.contains([',', '"', '\n', '\r']) { format!("\"{}\"", s.replace('"', "\"\"")) } else { s.to_string() }
    }

    fn set(id: i64, reason: Option<&str>, parameters: &[(&str, f64)]) -> api::ParameterSetItem {
        api::ParameterSetItem {
            id,
            calibration_id: 1,
            job: id - 1,
            stage: 0,
            parameters: parameters.iter().map(|(k, v)| (k.to_string(), *v)).collect(),
            status: if reason.is_some() { "failed" } else { "ok" }.into(),
            cost: reason.is_none().then_some(0.125 * id as f64),
            reason: reason.map(String::from),
            created: 0,
        }
    }

    #[test]
    fn parameter_sets_are_written_byte_for_byte_as_before() {
        let reason = "solver: step rejected at cell 3, \"T\" = -1\nsecond line\r";
        let items = [set(1, None, &[("b", 2.0), ("a", 1e-7)]), set(2, Some(reason), &[("a", 0.5)])];
        let text = parameter_sets(&items).expect("csv");
        let expected = format!(
            "id,job,stage,status,cost,reason,a,b\n1,0,0,ok,0.125,,0.0000001,2\n2,1,0,failed,,{},0.5,\n",
            hand_quoted(reason)
        );
        assert_eq!(text, expected);
    }

    #[test]
    fn results_are_written_byte_for_byte_as_before() {
        let item = api::ResultItem {
            id: 7,
            parameter_set_id: 3,
            job_id: 5,
            experiment_id: 2,
            status: "failed".into(),
            cost: None,
            reason: Some("a, \"b\"".into()),
            worker: Some("node 1".into()),
            duration_s: Some(1.5),
            breakdown: None,
            created: 0,
        };
        let text = results(&[item]).expect("csv");
        assert_eq!(
            text,
            "id,parameter_set_id,job_id,experiment_id,status,cost,reason,worker,duration_s\n\
             7,3,5,2,failed,,\"a, \"\"b\"\"\",node 1,1.5\n"
        );
        assert_eq!(results(&[]).expect("csv").lines().count(), 1, "the header alone");
    }

    #[test]
    fn a_quoted_field_with_a_comma_a_quote_and_a_newline_round_trips() {
        let reason = "x, \"y\"\nz";
        let text = parameter_sets(&[set(1, Some(reason), &[("p", 1.0)])]).expect("csv");
        let mut r = ::csv::ReaderBuilder::new().from_reader(text.as_bytes());
        let headers = r.headers().expect("header").clone();
        let rows: Vec<::csv::StringRecord> = r.records().collect::<Result<_, _>>().expect("rows");
        assert_eq!(rows.len(), 1);
        let reason_column = headers.iter().position(|h| h == "reason").expect("reason column");
        assert_eq!(&rows[0][reason_column], reason);
        assert_eq!(&rows[0][headers.iter().position(|h| h == "p").expect("p")], "1");
    }
}

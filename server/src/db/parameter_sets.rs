//! The `parameter_sets` table: the points a calibration's optimiser asked for, each with one job
//! per experiment, and the summed cost they are told with.

use sqlx::SqliteConnection;

use super::{DbError, ROWS_PER_STATEMENT, id_list, now_ms};

/// A parameter set to store: the pipeline's job id, its stage and the parameter values as JSON.
#[derive(Debug, Clone)]
pub struct NewParameterSet {
    /// The pipeline's job id.
    pub job: i64,
    /// Stage that asked for it.
    pub stage: i64,
    /// Parameter values JSON.
    pub parameters_json: String,
}

/// The id a stored parameter set got, with its pipeline job id.
#[derive(Debug, sqlx::FromRow)]
struct StoredSet {
    id: i64,
    job: i64,
}

/// Stores parameter sets (pipeline jobs) in the order given, each with one queued job per
/// experiment (job ids follow the sets' order, then the experiments' order), in two statements
/// per thousand sets.
pub async fn insert_parameter_sets(
    tx: &mut SqliteConnection,
    calibration_id: i64,
    sets: &[NewParameterSet],
    experiments: &[i64],
) -> Result<(), DbError> {
    let now = now_ms();
    for chunk in sets.chunks(ROWS_PER_STATEMENT) {
        let mut q = sqlx::QueryBuilder::<sqlx::Sqlite>::new(
            "INSERT INTO parameter_sets (calibration_id, job, stage, parameters_json, status, created) ",
        );
        q.push_values(chunk, |mut b, s| {
            b.push_bind(calibration_id)
                .push_bind(s.job)
                .push_bind(s.stage)
                .push_bind(&s.parameters_json)
                .push_bind("pending")
                .push_bind(now);
        });
        q.push(" RETURNING id, job");
        let rows: Vec<StoredSet> = q.build_query_as().persistent(false).fetch_all(&mut *tx).await?;
        let ids: std::collections::HashMap<i64, i64> = rows.iter().map(|r| (r.job, r.id)).collect();
        let mut jobs = Vec::with_capacity(chunk.len() * experiments.len());
        for s in chunk {
            let ps = *ids
                .get(&s.job)
                .ok_or_else(|| DbError::Corrupt(format!("parameter set of job {} was not stored", s.job)))?;
            jobs.extend(experiments.iter().map(|&e| (ps, e)));
        }
        for part in jobs.chunks(ROWS_PER_STATEMENT) {
            let mut q = sqlx::QueryBuilder::<sqlx::Sqlite>::new(
                "INSERT INTO jobs (calibration_id, parameter_set_id, experiment_id, status, created) ",
            );
            q.push_values(part, |mut b, &(ps, e)| {
                b.push_bind(calibration_id).push_bind(ps).push_bind(e).push_bind("queued").push_bind(now);
            });
            q.build().persistent(false).execute(&mut *tx).await?;
        }
    }
    Ok(())
}

/// One job of a parameter set, with the set's calibration and pipeline job id.
#[derive(Debug, Clone, sqlx::FromRow)]
pub struct SetPart {
    /// Parameter set.
    pub parameter_set_id: i64,
    /// Its calibration.
    pub calibration_id: i64,
    /// Its pipeline job id.
    pub pipeline_job: i64,
    /// The job's status.
    pub status: String,
    /// The job's cost.
    pub cost: Option<f64>,
    /// The job's failure reason.
    pub reason: Option<String>,
}

/// The jobs of pending parameter sets, by set and then job id (= experiment order).
pub async fn pending_set_parts(tx: &mut SqliteConnection, sets: &[i64]) -> Result<Vec<SetPart>, DbError> {
    let ids = id_list(sets)?;
    let parts = sqlx::query_as(
        "SELECT j.parameter_set_id AS parameter_set_id, p.calibration_id AS calibration_id, p.job AS pipeline_job,
                j.status AS status, j.cost AS cost, j.reason AS reason
         FROM jobs j JOIN parameter_sets p ON p.id = j.parameter_set_id
         WHERE j.parameter_set_id IN (SELECT value FROM json_each(?)) AND p.status = 'pending'
         ORDER BY j.parameter_set_id, j.id",
    )
    .bind(ids)
    .fetch_all(tx)
    .await?;
    Ok(parts)
}

/// A finished parameter set: (id, `ok` or `failed`, summed cost, reason).
pub type FinishedSet<'a> = (i64, &'static str, Option<f64>, Option<&'a str>);

/// Finishes parameter sets (one statement per thousand).
pub async fn finish_parameter_sets(tx: &mut SqliteConnection, sets: &[FinishedSet<'_>]) -> Result<(), DbError> {
    for chunk in sets.chunks(ROWS_PER_STATEMENT) {
        let mut q = sqlx::QueryBuilder::<sqlx::Sqlite>::new(
            "UPDATE parameter_sets SET status = v.column2, cost = v.column3, reason = v.column4 FROM (",
        );
        q.push_values(chunk, |mut b, &(id, status, cost, reason)| {
            b.push_bind(id).push_bind(status).push_bind(cost).push_bind(reason);
        });
        q.push(") AS v WHERE parameter_sets.id = v.column1");
        q.build().persistent(false).execute(&mut *tx).await?;
    }
    Ok(())
}

//! The `workers` table: who claimed, with how many slots, when last seen, how many results.

use std::collections::BTreeMap;

use sqlx::{SqliteConnection, SqlitePool};

use super::{DbError, now_ms};

/// Records a worker's claim (name, slots, time).
pub async fn touch_worker(tx: &mut SqliteConnection, name: &str, slots: i64) -> Result<(), DbError> {
    sqlx::query(
        "INSERT INTO workers (name, slots, last_heartbeat) VALUES (?1, ?2, ?3)
         ON CONFLICT (name) DO UPDATE SET slots = ?2, last_heartbeat = ?3",
    )
    .bind(name)
    .bind(slots)
    .bind(now_ms())
    .execute(tx)
    .await?;
    Ok(())
}

/// Slots of the workers seen since `since_ms`.
pub async fn active_slots(tx: &mut SqliteConnection, since_ms: i64) -> Result<i64, DbError> {
    let slots = sqlx::query_scalar("SELECT COALESCE(SUM(slots), 0) FROM workers WHERE last_heartbeat >= ?")
        .bind(since_ms)
        .fetch_one(tx)
        .await?;
    Ok(slots)
}

/// Counts `n` results for a worker and marks it seen.
pub async fn count_evaluations(tx: &mut SqliteConnection, worker: &str, n: i64) -> Result<(), DbError> {
    sqlx::query("UPDATE workers SET evaluations = evaluations + ?, last_heartbeat = ? WHERE name = ?")
        .bind(n)
        .bind(now_ms())
        .bind(worker)
        .execute(tx)
        .await?;
    Ok(())
}

/// A worker as the coordinator last saw it.
#[derive(Debug, Clone, PartialEq, sqlx::FromRow)]
pub struct WorkerRow {
    /// Its name.
    pub name: String,
    /// Simulation slots it claimed with.
    pub slots: i64,
    /// Last claim, heartbeat or result, Unix ms.
    pub last_heartbeat: i64,
    /// Results it reported.
    pub evaluations: i64,
}

/// Every worker, most recently seen first.
pub async fn workers(pool: &SqlitePool) -> Result<Vec<WorkerRow>, DbError> {
    let rows = sqlx::query_as(
        "SELECT name, slots, last_heartbeat, evaluations FROM workers ORDER BY last_heartbeat DESC, name",
    )
    .fetch_all(pool)
    .await?;
    Ok(rows)
}

/// Results counted for one worker.
#[derive(Debug, sqlx::FromRow)]
struct WorkerCount {
    worker: String,
    n: i64,
}

/// Results recorded since `since_ms`, per worker name.
pub async fn results_per_worker_since(pool: &SqlitePool, since_ms: i64) -> Result<BTreeMap<String, i64>, DbError> {
    let rows: Vec<WorkerCount> = sqlx::query_as(
        "SELECT worker, COUNT(*) AS n FROM cost_results WHERE created >= ? AND worker IS NOT NULL GROUP BY worker",
    )
    .bind(since_ms)
    .fetch_all(pool)
    .await?;
    Ok(rows.into_iter().map(|r| (r.worker, r.n)).collect())
}

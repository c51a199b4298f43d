//! The `coordinator_lock` table: one row naming the coordinator that serves the database (see
//! [`crate::lock`] for the policy).

use sqlx::SqliteConnection;

use super::DbError;

/// The lock row as stored.
#[derive(Debug, Clone, sqlx::FromRow)]
pub struct LockRow {
    /// Host of the holder.
    pub host: String,
    /// Its pid.
    pub pid: i64,
    /// Where it listens.
    pub address: String,
    /// When it took the lock, Unix ms.
    pub started: i64,
    /// When the lock expires without renewal, Unix ms.
    pub expires: i64,
}

/// A lock to write: the holder's random id with its [`LockRow`].
#[derive(Debug, Clone, Copy)]
pub struct NewLock<'a> {
    /// Random id of the holding process.
    pub holder: &'a str,
    /// Host of the holder.
    pub host: &'a str,
    /// Its pid.
    pub pid: i64,
    /// Where it listens.
    pub address: &'a str,
    /// Now, Unix ms.
    pub started: i64,
    /// Expiry, Unix ms.
    pub expires: i64,
}

/// The lock row, if any coordinator holds or held the lock.
pub async fn holder(tx: &mut SqliteConnection) -> Result<Option<LockRow>, DbError> {
    let row = sqlx::query_as("SELECT host, pid, address, started, expires FROM coordinator_lock WHERE id = 1")
        .fetch_optional(tx)
        .await?;
    Ok(row)
}

/// Writes the lock row, replacing any earlier holder.
pub async fn take(tx: &mut SqliteConnection, l: &NewLock<'_>) -> Result<(), DbError> {
    sqlx::query(
        "INSERT INTO coordinator_lock (id, holder, host, pid, address, started, expires) VALUES (1, ?, ?, ?, ?, ?, ?)
         ON CONFLICT (id) DO UPDATE SET holder = excluded.holder, host = excluded.host, pid = excluded.pid,
             address = excluded.address, started = excluded.started, expires = excluded.expires",
    )
    .bind(l.holder)
    .bind(l.host)
    .bind(l.pid)
    .bind(l.address)
    .bind(l.started)
    .bind(l.expires)
    .execute(tx)
    .await?;
    Ok(())
}

/// Moves the expiry of `holder`'s lock to `expires_ms`; returns the rows changed (0 when another
/// coordinator holds the lock now).
pub async fn renew(tx: &mut SqliteConnection, holder: &str, expires_ms: i64) -> Result<u64, DbError> {
    let done = sqlx::query("UPDATE coordinator_lock SET expires = ? WHERE id = 1 AND holder = ?")
        .bind(expires_ms)
        .bind(holder)
        .execute(tx)
        .await?;
    Ok(done.rows_affected())
}

/// Deletes `holder`'s lock.
pub async fn release(tx: &mut SqliteConnection, holder: &str) -> Result<(), DbError> {
    sqlx::query("DELETE FROM coordinator_lock WHERE id = 1 AND holder = ?").bind(holder).execute(tx).await?;
    Ok(())
}

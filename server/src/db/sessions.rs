//! The `sessions` table: dashboard sessions, by the SHA-256 of their id, with an expiry.

use sqlx::{SqliteConnection, SqlitePool};

use super::DbError;

/// Stores a session by the digest of its id.
pub async fn insert_session(
    tx: &mut SqliteConnection,
    digest: &str,
    created: i64,
    expires: i64,
) -> Result<(), DbError> {
    sqlx::query("INSERT INTO sessions (digest, created, expires) VALUES (?, ?, ?)")
        .bind(digest)
        .bind(created)
        .bind(expires)
        .execute(tx)
        .await?;
    Ok(())
}

/// True when a session with this digest is stored and has not expired at `now_ms`.
pub async fn session_valid(pool: &SqlitePool, digest: &str, now_ms: i64) -> Result<bool, DbError> {
    let found: Option<i64> = sqlx::query_scalar("SELECT 1 FROM sessions WHERE digest = ? AND expires > ?")
        .bind(digest)
        .bind(now_ms)
        .fetch_optional(pool)
        .await?;
    Ok(found.is_some())
}

/// Revokes a session.
pub async fn delete_session(tx: &mut SqliteConnection, digest: &str) -> Result<(), DbError> {
    sqlx::query("DELETE FROM sessions WHERE digest = ?").bind(digest).execute(tx).await?;
    Ok(())
}

/// Forgets sessions that expired before `now_ms`.
pub async fn delete_expired_sessions(tx: &mut SqliteConnection, now_ms: i64) -> Result<(), DbError> {
    sqlx::query("DELETE FROM sessions WHERE expires <= ?").bind(now_ms).execute(tx).await?;
    Ok(())
}

//! Every SQL statement of the coordinator, by table: `experiments`, `calibrations`,
//! `parameter_sets`, `jobs` (with the results workers report), `workers`, `history` (the pages of
//! a calibration's parameter sets and results), `sessions` (the dashboard's) and [`lock`] (the
//! coordinator's lock row). Their functions are re-exported here: callers write `db::claim`.
//!
//! SQLite in WAL mode with `synchronous = NORMAL`. Reads go through a pool of reader connections;
//! writes go through a single writer connection and start with `BEGIN IMMEDIATE` ([`Db::begin`]),
//! so a write transaction never fails half-way with `SQLITE_BUSY`. Functions take a pool (reads) or
//! a connection inside a transaction (writes) and return [`DbError`], with a distinct
//! [`DbError::NotFound`]; the routes map errors to HTTP statuses. Rows are read into
//! [`sqlx::FromRow`] structs by column name, so a column of an unexpected type is an error, never
//! a panic.

mod calibrations;
mod experiments;
mod history;
mod jobs;
pub mod lock;
mod parameter_sets;
mod sessions;
mod workers;

use std::str::FromStr;
use std::time::Duration;

use sqlx::SqlitePool;
use sqlx::sqlite::{SqliteConnectOptions, SqliteJournalMode, SqlitePoolOptions, SqliteSynchronous};

pub use crate::clock::now_ms;
pub use calibrations::*;
pub use experiments::*;
pub use history::*;
pub use jobs::*;
pub use parameter_sets::*;
pub use sessions::*;
pub use workers::*;

/// A storage error.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum DbError {
    /// The row does not exist.
    #[error("{what} {id} does not exist")]
    NotFound {
        /// Kind of row (`experiment`, `calibration`, `job`).
        what: &'static str,
        /// Its id.
        id: i64,
    },
    /// A stored value cannot be read back.
    #[error("stored data is corrupt: {0}")]
    Corrupt(String),
    /// The database refused or failed.
    #[error("database: {0}")]
    Sqlx(#[from] sqlx::Error),
    /// A migration failed.
    #[error("database migration: {0}")]
    Migrate(#[from] sqlx::migrate::MigrateError),
}

/// A write transaction.
pub type Tx = sqlx::Transaction<'static, sqlx::Sqlite>;

/// Rows per multi-row statement (SQLite allows 32 766 bound values; 11 per row at most here).
const ROWS_PER_STATEMENT: usize = 1000;

/// A list of ids as JSON, for `json_each(?)`.
fn id_list(ids: &[i64]) -> Result<String, DbError> {
    serde_json::to_string(ids).map_err(|e| DbError::Corrupt(e.to_string()))
}

/// The coordinator's database: reader pool and one writer connection.
#[derive(Debug, Clone)]
pub struct Db {
    read: SqlitePool,
    write: SqlitePool,
    /// Why the last write failed, `None` after a successful one.
    write_error: std::sync::Arc<std::sync::Mutex<Option<String>>>,
}

impl Db {
    /// Opens (creating it if absent) the SQLite database at `url` (`sqlite://path` or a plain
    /// path) and runs the migrations.
    pub async fn open(url: &str) -> Result<Self, DbError> {
        let url = if url.starts_with("sqlite:") { url.to_string() } else { format!("sqlite://{url}") };
        let options = SqliteConnectOptions::from_str(&url)?
            .create_if_missing(true)
            .journal_mode(SqliteJournalMode::Wal)
            .synchronous(SqliteSynchronous::Normal)
            .busy_timeout(Duration::from_secs(10))
            .foreign_keys(true);
        // A write that failed (disk full, file size limit, I/O error) can leave the connection
        // inside a transaction that SQLite already ended, which sqlx still counts as open: every
        // later `BEGIN` would fail with "non-zero transaction depth". Such a connection is closed
        // when it is next taken from the pool, and a fresh one is opened.
        let write = SqlitePoolOptions::new()
            .max_connections(1)
            .before_acquire(|conn, _| {
                Box::pin(async move {
                    use sqlx::Connection as _;
                    if conn.is_in_transaction() {
                        tracing::warn!("the writer connection was left inside a failed transaction: reopening it");
                        return Ok(false);
                    }
                    Ok(true)
                })
            })
            .connect_with(options.clone())
            .await?;
        sqlx::migrate!("../migrations").run(&write).await?;
        let read = SqlitePoolOptions::new().max_connections(4).connect_with(options.read_only(true)).await?;
        Ok(Self { read, write, write_error: Default::default() })
    }

    /// Starts a write transaction (`BEGIN IMMEDIATE` on the writer connection).
    pub async fn begin(&self) -> Result<Tx, DbError> {
        let tx = self.write.begin_with("BEGIN IMMEDIATE").await;
        self.note(tx.as_ref().err());
        Ok(tx?)
    }

    /// Commits a write transaction, recording the outcome for [`Db::write_error`].
    pub async fn commit(&self, tx: Tx) -> Result<(), DbError> {
        let done = tx.commit().await;
        self.note(done.as_ref().err());
        Ok(done?)
    }

    fn note(&self, e: Option<&sqlx::Error>) {
        if let Ok(mut w) = self.write_error.lock() {
            *w = e.map(|e| e.to_string());
        }
    }

    /// Why the last write transaction failed to start or commit, if it did.
    pub fn write_error(&self) -> Option<String> {
        self.write_error.lock().ok().and_then(|w| w.clone())
    }

    /// The writer pool (for tests that need to reach the writer connection itself).
    #[doc(hidden)]
    pub fn writer(&self) -> &SqlitePool {
        &self.write
    }

    /// The reader pool.
    pub fn reader(&self) -> &SqlitePool {
        &self.read
    }

    /// Closes both pools.
    pub async fn close(&self) {
        self.read.close().await;
        self.write.close().await;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    async fn scratch_db(tag: &str) -> (Db, std::path::PathBuf) {
        let dir = std::env::temp_dir().join(format!("cryofit-db-{tag}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).expect("scratch dir");
        let db = Db::open(&dir.join("c.db").display().to_string()).await.expect("open");
        (db, dir)
    }

    async fn store(db: &Db, data: &str) -> Result<i64, DbError> {
        let mut tx = db.begin().await?;
        let id = insert_experiment(&mut tx, "e", "nitrogen", "case", data).await?;
        db.commit(tx).await?;
        Ok(id)
    }

    #[tokio::test]
    async fn a_transaction_that_failed_under_sqlx_does_not_wedge_later_writes() {
        let (db, dir) = scratch_db("wedge").await;
        // SQLite ends the transaction behind sqlx's back, as an I/O error during COMMIT does: the
        // COMMIT fails and sqlx still counts the transaction as open
        let mut tx = db.begin().await.expect("begin");
        sqlx::query("ROLLBACK").execute(&mut *tx).await.expect("rollback");
        let e = db.commit(tx).await.expect_err("nothing to commit");
        assert!(e.to_string().contains("no transaction is active"), "{e}");
        assert!(db.write_error().is_some());
        // before: "attempted to call begin_with at non-zero transaction depth", for every write
        for k in 0..3 {
            store(&db, "x").await.unwrap_or_else(|e| panic!("write {k} after the failure: {e}"));
        }
        assert_eq!(db.write_error(), None);
        db.close().await;
        let _ = std::fs::remove_dir_all(dir);
    }

    #[tokio::test]
    async fn a_full_database_fails_one_write_and_the_next_ones_work_again() {
        let (db, dir) = scratch_db("full").await;
        store(&db, "small").await.expect("first write");
        // the file may not grow: the disk is full as far as SQLite can tell
        let pages: i64 = sqlx::query_scalar("PRAGMA page_count").fetch_one(db.writer()).await.expect("page count");
        sqlx::query(&format!("PRAGMA max_page_count = {}", pages + 1)).execute(db.writer()).await.expect("limit");
        let big = "x".repeat(1 << 20);
        let e = store(&db, &big).await.expect_err("a megabyte does not fit");
        assert!(e.to_string().contains("full"), "{e}");
        store(&db, "small again").await.expect("a small write after the failed one");
        db.close().await;
        let _ = std::fs::remove_dir_all(dir);
    }
}

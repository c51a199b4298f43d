//! The coordinator's exclusive lock on its database: one row of `coordinator_lock` naming the
//! holding process (a random id, host, pid, address) with an expiry it renews every few seconds.
//!
//! A second coordinator on the same database refuses to start while the row names a live holder,
//! and says which. A holder that stopped cleanly deleted its row; one that was killed left a row
//! that is taken over at once when it names a process of this host that no longer runs (or this
//! very pid: a restarted container), and otherwise once its expiry has passed.
//!
//! The first write of a coordinator is taking this lock, so a database that cannot be written
//! (a read-only file or mount, a full disk) is refused at start.

use std::time::Duration;

use rand::Rng;

use crate::clock::{now_ms, utc};
use crate::db::{self, Db, DbError};

/// A held lock.
#[derive(Debug, Clone)]
pub struct DbLock {
    holder: String,
    ttl: Duration,
}

/// Why the lock could not be taken.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum LockError {
    /// Another coordinator holds it.
    #[error(
        "another coordinator serves this database: pid {pid} on host `{host}`, listening on {address}, since {since}; \
         stop it first, or give this one another --database"
    )]
    Held {
        /// Its host.
        host: String,
        /// Its pid.
        pid: i64,
        /// Where it listens.
        address: String,
        /// When it started (UTC).
        since: String,
    },
    /// The database cannot be written.
    #[error(
        "the database cannot be written ({0}); the coordinator needs a writable database file: check its \
         permissions, the free space of its disk and that it is not opened read-only (mode=ro)"
    )]
    Unwritable(String),
    /// Storage failed otherwise.
    #[error(transparent)]
    Db(#[from] DbError),
}

/// This machine's host name.
pub fn host_name() -> String {
    std::fs::read_to_string("/proc/sys/kernel/hostname")
        .ok()
        .or_else(|| std::env::var("HOSTNAME").ok())
        .map(|h| h.trim().to_string())
        .filter(|h| !h.is_empty())
        .unwrap_or_else(|| "unknown".into())
}

/// True when `pid` names no running process of this host (known only where `/proc` exists).
fn gone(pid: i64) -> bool {
    let proc = std::path::Path::new("/proc");
    proc.join("self").exists() && !proc.join(pid.to_string()).exists()
}

fn unwritable(e: DbError) -> LockError {
    match e {
        DbError::Sqlx(e) => LockError::Unwritable(e.to_string()),
        other => LockError::Unwritable(other.to_string()),
    }
}

impl DbLock {
    /// Takes the lock for this process, listening on `address`, or says who holds it.
    pub async fn acquire(db: &Db, address: &str, ttl: Duration) -> Result<Self, LockError> {
        let holder = format!("{:032x}", rand::thread_rng().r#gen::<u128>());
        let host = host_name();
        let pid = i64::from(std::process::id());
        let now = now_ms();
        let mut tx = db.begin().await.map_err(unwritable)?;
        if let Some(r) = db::lock::holder(&mut tx).await? {
            let dead = r.host == host && (r.pid == pid || gone(r.pid));
            if r.expires > now && !dead {
                return Err(LockError::Held { host: r.host, pid: r.pid, address: r.address, since: utc(r.started) });
            }
            tracing::warn!(host = %r.host, pid = r.pid, address = %r.address, "taking over the lock of a coordinator that stopped without releasing it");
        }
        let expires = now + ttl.as_millis() as i64;
        db::lock::take(
            &mut tx,
            &db::lock::NewLock { holder: &holder, host: &host, pid, address, started: now, expires },
        )
        .await
        .map_err(unwritable)?;
        db.commit(tx).await.map_err(unwritable)?;
        tracing::info!(%host, pid, "took the database lock");
        Ok(Self { holder, ttl })
    }

    /// How often [`DbLock::renew`] should run.
    pub fn renew_every(&self) -> Duration {
        self.ttl / 5
    }

    /// Extends the lock: a real write, so it also tells whether the database can be written.
    /// Errors say why (the write failed, or another coordinator took the lock).
    pub async fn renew(&self, db: &Db) -> Result<(), String> {
        let write = async {
            let mut tx = db.begin().await?;
            let changed = db::lock::renew(&mut tx, &self.holder, now_ms() + self.ttl.as_millis() as i64).await?;
            db.commit(tx).await?;
            Ok::<_, DbError>(changed)
        };
        match write.await {
            Ok(1) => Ok(()),
            Ok(_) => Err("another coordinator took the database lock".into()),
            Err(e) => Err(format!("the database cannot be written: {e}")),
        }
    }

    /// Gives the lock up (when the coordinator stops).
    pub async fn release(&self, db: &Db) {
        let done = async {
            let mut tx = db.begin().await?;
            db::lock::release(&mut tx, &self.holder).await?;
            db.commit(tx).await
        };
        if let Err(e) = done.await {
            tracing::warn!(error = %e, "could not release the database lock (it expires by itself)");
        }
    }
}

-- The coordinator's lock on its database, and the dashboard's sessions.
-- Never edit this file after it lands: add a new timestamped migration instead.

-- One row while a coordinator serves this database: who holds it and until when. The holder
-- renews `expires` every few seconds and deletes the row when it stops; another coordinator
-- refuses to start while the row names a live holder.
CREATE TABLE coordinator_lock (
    id       INTEGER PRIMARY KEY CHECK (id = 1),
    holder   TEXT    NOT NULL,   -- random id of the holding process
    host     TEXT    NOT NULL,
    pid      INTEGER NOT NULL,
    address  TEXT    NOT NULL,   -- where it listens
    started  INTEGER NOT NULL,
    expires  INTEGER NOT NULL
);

-- Dashboard sessions: the cookie holds a random 256-bit id; the row holds its SHA-256 (hex), so
-- that a copy of the database gives no usable cookie. Signing out deletes the row.
CREATE TABLE sessions (
    digest   TEXT    PRIMARY KEY,
    created  INTEGER NOT NULL,
    expires  INTEGER NOT NULL
);
CREATE INDEX sessions_expires ON sessions (expires);

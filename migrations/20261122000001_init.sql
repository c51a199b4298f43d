-- cryofit coordinator schema. Times are Unix milliseconds; JSON columns hold serde_json text.
-- Never edit this file after it lands: add a new timestamped migration instead.

CREATE TABLE experiments (
    id          INTEGER PRIMARY KEY AUTOINCREMENT,
    name        TEXT    NOT NULL,
    fluid       TEXT    NOT NULL,
    case_text   TEXT    NOT NULL,
    data_text   TEXT    NOT NULL,
    created     INTEGER NOT NULL
);

CREATE TABLE calibrations (
    id                   INTEGER PRIMARY KEY AUTOINCREMENT,
    name                 TEXT    NOT NULL,
    spec_json            TEXT    NOT NULL,
    experiment_ids_json  TEXT    NOT NULL,
    status               TEXT    NOT NULL CHECK (status IN ('queued', 'running', 'completed', 'failed', 'cancelled')),
    budget               INTEGER NOT NULL,
    evaluations          INTEGER NOT NULL DEFAULT 0,
    failed_evaluations   INTEGER NOT NULL DEFAULT 0,
    stage                INTEGER NOT NULL DEFAULT 0,
    best_cost            REAL,
    best_parameters_json TEXT,
    reports_json         TEXT    NOT NULL DEFAULT '[]',
    pipeline_state_json  TEXT    NOT NULL,
    solver_version       TEXT    NOT NULL,
    fluid_hashes         TEXT    NOT NULL,
    error                TEXT,
    created              INTEGER NOT NULL,
    updated              INTEGER NOT NULL
);
CREATE INDEX calibrations_status ON calibrations (status);

CREATE TABLE parameter_sets (
    id              INTEGER PRIMARY KEY AUTOINCREMENT,
    calibration_id  INTEGER NOT NULL REFERENCES calibrations (id),
    job             INTEGER NOT NULL,              -- the pipeline's Job.id
    stage           INTEGER NOT NULL,
    parameters_json TEXT    NOT NULL,
    cost            REAL,
    reason          TEXT,
    status          TEXT    NOT NULL CHECK (status IN ('pending', 'ok', 'failed')),
    created         INTEGER NOT NULL,
    UNIQUE (calibration_id, job)
);
CREATE INDEX parameter_sets_history ON parameter_sets (calibration_id, id);
CREATE INDEX parameter_sets_status ON parameter_sets (calibration_id, status, id);

CREATE TABLE jobs (
    id               INTEGER PRIMARY KEY AUTOINCREMENT,
    calibration_id   INTEGER NOT NULL REFERENCES calibrations (id),
    parameter_set_id INTEGER NOT NULL REFERENCES parameter_sets (id),
    experiment_id    INTEGER NOT NULL REFERENCES experiments (id),
    status           TEXT    NOT NULL CHECK (status IN ('queued', 'leased', 'done', 'failed')),
    lease_id         TEXT,
    lease_owner      TEXT,
    lease_expires    INTEGER,
    attempts         INTEGER NOT NULL DEFAULT 0,
    cost             REAL,
    reason           TEXT,
    duration         REAL,
    created          INTEGER NOT NULL
);
-- the claim: oldest queued jobs first
CREATE INDEX jobs_claim ON jobs (status, id);
-- the reaper: expired leases
CREATE INDEX jobs_lease ON jobs (status, lease_expires);
-- completion of a parameter set
CREATE INDEX jobs_parameter_set ON jobs (parameter_set_id);
-- queue depth per calibration
CREATE INDEX jobs_calibration ON jobs (calibration_id, status);

CREATE TABLE cost_results (
    id               INTEGER PRIMARY KEY AUTOINCREMENT,
    calibration_id   INTEGER NOT NULL REFERENCES calibrations (id),
    job_id           INTEGER NOT NULL REFERENCES jobs (id),
    parameter_set_id INTEGER NOT NULL REFERENCES parameter_sets (id),
    experiment_id    INTEGER NOT NULL REFERENCES experiments (id),
    status           TEXT    NOT NULL CHECK (status IN ('ok', 'failed', 'stale')),
    cost             REAL,
    reason           TEXT,
    worker           TEXT,
    duration         REAL,
    breakdown_json   TEXT,
    created          INTEGER NOT NULL
);
CREATE INDEX cost_results_history ON cost_results (calibration_id, id);

CREATE TABLE workers (
    id             INTEGER PRIMARY KEY AUTOINCREMENT,
    name           TEXT    NOT NULL UNIQUE,
    slots          INTEGER NOT NULL DEFAULT 1,
    last_heartbeat INTEGER NOT NULL,
    evaluations    INTEGER NOT NULL DEFAULT 0
);
CREATE INDEX workers_recent ON workers (last_heartbeat);

//! The job store on a PostgreSQL server (`--store postgres://...`), which several
//! coordinators may share, one of them leading.
//!
//! **Its own thread.** rust-postgres's blocking client runs a small async runtime of its
//! own and must not be driven from one of the coordinator's runtime threads, so the
//! connection lives on a thread of the store's, and every call is sent to it and waited
//! for. The caller blocks, whichever thread it is on; nothing panics.
//!
//! **Outages.** A call that finds the connection broken drops it; the next call connects
//! again, but no sooner than a backoff that doubles from a quarter of a second to five
//! seconds while the server stays away. Until then calls fail at once with the last
//! reason, naming the server (never its password), so the coordinator refuses work with a
//! clear 503 rather than waiting on a dead socket. Connecting and every read and write are
//! bounded in time (connect and TCP user timeouts), so a server that stops answering is an
//! error within seconds, not a hang.
//!
//! **Leadership and fencing.** The `leader` row names the coordinator that leads, its
//! address and its epoch. A coordinator takes the row when it is free or its holder has
//! not renewed it for the leader TTL (the database's clock decides, not the coordinators'),
//! which raises the epoch; it renews it every second. The leader's connection carries its
//! epoch (`SET kiln.epoch`), and a trigger on every table (`kiln_fence()`) reads the row
//! under a share lock before each write statement and refuses it unless the epoch is still
//! the writer's: a coordinator deposed while it was away cannot write, even once, and a
//! takeover waits for the writes already under way. The database enforces it, so each
//! write is still one statement and one round trip.
//!
//! **Round trips.** Statements are prepared once per connection and kept, so a call is one
//! round trip to the server.
//!
//! **Schema.** `kiln_schema` holds the version; [`MIGRATIONS`] are applied in order, each
//! in a transaction under an advisory lock, so that two coordinators starting at once
//! upgrade it once.

use super::{JobStore, KeptTile, Leadership, StoreError, StoredJob, StoredToken, WebhookOutcome};
use crate::api::{JobSpec, JobState, Role};
use postgres::types::ToSql;
use postgres::{Client, NoTls, Row, Statement};
use std::collections::BTreeSet;
use std::collections::HashMap;
use std::sync::mpsc;
use std::time::{Duration, Instant};

/// One change to the schema: the version it brings the store to, and its SQL.
struct Migration {
    version: i32,
    sql: &'static str,
}

/// Every schema change, oldest first. Version 1 is SQLite's version 3 (jobs, tile passes,
/// notes, workers set aside, tokens) with leadership; there was never a Postgres store
/// without passes, so there is no table of finished tiles from before them.
const MIGRATIONS: &[Migration] = &[Migration {
    version: 1,
    sql: "CREATE TABLE jobs (id BIGSERIAL PRIMARY KEY, spec TEXT NOT NULL, state TEXT NOT NULL, error TEXT, idempotency_key TEXT UNIQUE);
          CREATE TABLE tile_passes (job BIGINT NOT NULL, idx BIGINT NOT NULL, samples BIGINT NOT NULL, exr BYTEA NOT NULL, unchecked_by TEXT NOT NULL DEFAULT '[]', PRIMARY KEY (job, idx, samples));
          CREATE TABLE meta (key TEXT PRIMARY KEY, value BIGINT NOT NULL);
          CREATE TABLE set_aside (worker TEXT PRIMARY KEY, reason TEXT NOT NULL);
          CREATE TABLE job_notes (job BIGINT PRIMARY KEY, verified BIGINT NOT NULL DEFAULT 0, webhook BIGINT NOT NULL DEFAULT 0);
          CREATE TABLE tokens (id BIGSERIAL PRIMARY KEY, role TEXT NOT NULL, name TEXT NOT NULL, hash TEXT NOT NULL UNIQUE, revoked BOOLEAN NOT NULL DEFAULT false);
          CREATE TABLE leader (id INTEGER PRIMARY KEY CHECK (id = 1), holder TEXT NOT NULL, address TEXT NOT NULL, epoch BIGINT NOT NULL, renewed TIMESTAMPTZ NOT NULL);
          CREATE FUNCTION kiln_fence() RETURNS trigger LANGUAGE plpgsql AS $$
          DECLARE
              mine TEXT := current_setting('kiln.epoch', true);
              lead_epoch BIGINT;
              lead_holder TEXT;
          BEGIN
              IF mine IS NULL OR mine = '' THEN
                  RETURN NULL;
              END IF;
              SELECT epoch, holder INTO lead_epoch, lead_holder FROM leader WHERE id = 1 FOR SHARE;
              IF lead_epoch IS DISTINCT FROM mine::BIGINT THEN
                  RAISE EXCEPTION '% took the lead at epoch %', lead_holder, lead_epoch USING ERRCODE = 'KL001';
              END IF;
              RETURN NULL;
          END $$;
          CREATE TRIGGER fence BEFORE INSERT OR UPDATE OR DELETE ON jobs FOR EACH STATEMENT EXECUTE FUNCTION kiln_fence();
          CREATE TRIGGER fence BEFORE INSERT OR UPDATE OR DELETE ON tile_passes FOR EACH STATEMENT EXECUTE FUNCTION kiln_fence();
          CREATE TRIGGER fence BEFORE INSERT OR UPDATE OR DELETE ON meta FOR EACH STATEMENT EXECUTE FUNCTION kiln_fence();
          CREATE TRIGGER fence BEFORE INSERT OR UPDATE OR DELETE ON set_aside FOR EACH STATEMENT EXECUTE FUNCTION kiln_fence();
          CREATE TRIGGER fence BEFORE INSERT OR UPDATE OR DELETE ON job_notes FOR EACH STATEMENT EXECUTE FUNCTION kiln_fence();
          CREATE TRIGGER fence BEFORE INSERT OR UPDATE OR DELETE ON tokens FOR EACH STATEMENT EXECUTE FUNCTION kiln_fence();",
}];

/// The SQLSTATE `kiln_fence()` raises for a write by a coordinator that no longer leads.
const DEPOSED: &str = "KL001";

/// The advisory lock key migrations are applied under ("kiln" in ASCII).
const MIGRATION_LOCK: i64 = 0x6b69_6c6e;
/// How long connecting, and then any one read or write on the socket, may take.
const IO_TIMEOUT: Duration = Duration::from_secs(5);
const FIRST_BACKOFF: Duration = Duration::from_millis(250);
const MAX_BACKOFF: Duration = Duration::from_secs(5);

/// Why a call on the store's thread failed.
enum Failure {
    Db(postgres::Error),
    /// The leader row's epoch is no longer this coordinator's: the trigger's words.
    Deposed(String),
    /// No connection, and the backoff has not run out.
    Away(String),
}

impl From<postgres::Error> for Failure {
    fn from(e: postgres::Error) -> Failure {
        match e.as_db_error() {
            Some(db) if db.code().code() == DEPOSED => Failure::Deposed(db.message().to_string()),
            _ => Failure::Db(e),
        }
    }
}

/// The connection with its prepared statements, as calls use it.
struct Db<'a> {
    client: &'a mut Client,
    prepared: &'a mut HashMap<&'static str, Statement>,
}

impl Db<'_> {
    fn statement(&mut self, sql: &'static str) -> Result<Statement, postgres::Error> {
        if let Some(s) = self.prepared.get(sql) {
            return Ok(s.clone());
        }
        let s = self.client.prepare(sql)?;
        self.prepared.insert(sql, s.clone());
        Ok(s)
    }

    fn execute(
        &mut self,
        sql: &'static str,
        params: &[&(dyn ToSql + Sync)],
    ) -> Result<u64, postgres::Error> {
        let s = self.statement(sql)?;
        self.client.execute(&s, params)
    }

    fn query(
        &mut self,
        sql: &'static str,
        params: &[&(dyn ToSql + Sync)],
    ) -> Result<Vec<Row>, postgres::Error> {
        let s = self.statement(sql)?;
        self.client.query(&s, params)
    }

    fn query_one(
        &mut self,
        sql: &'static str,
        params: &[&(dyn ToSql + Sync)],
    ) -> Result<Row, postgres::Error> {
        let s = self.statement(sql)?;
        self.client.query_one(&s, params)
    }

    fn query_opt(
        &mut self,
        sql: &'static str,
        params: &[&(dyn ToSql + Sync)],
    ) -> Result<Option<Row>, postgres::Error> {
        let s = self.statement(sql)?;
        self.client.query_opt(&s, params)
    }
}

/// The connection, owned by the store's thread.
struct Conn {
    config: postgres::Config,
    /// Where the server is, as errors name it.
    name: String,
    client: Option<Client>,
    /// The statements prepared on `client`.
    prepared: HashMap<&'static str, Statement>,
    /// Why the last connection attempt failed, and when the next may be made.
    away: Option<(String, Instant, Duration)>,
    /// The epoch this coordinator leads under, once it does: every write checks it.
    fence: Option<i64>,
}

impl Conn {
    /// The connection, connecting again once the backoff allows.
    fn client(&mut self) -> Result<&mut Client, Failure> {
        if self.client.as_ref().is_some_and(|c| c.is_closed()) {
            self.client = None;
            self.prepared.clear();
        }
        if self.client.is_none() {
            if let Some((why, next, _)) = &self.away
                && Instant::now() < *next
            {
                return Err(Failure::Away(why.clone()));
            }
            let connected = self.config.connect(NoTls).and_then(|mut c| {
                // A leader's new connection carries its epoch, which fences its writes.
                if let Some(epoch) = self.fence {
                    c.batch_execute(&format!("SET kiln.epoch = '{epoch}'"))?;
                }
                Ok(c)
            });
            match connected {
                Ok(c) => {
                    if self.away.take().is_some() {
                        tracing::info!("the job store at {} answers again", self.name);
                    }
                    self.client = Some(c);
                }
                Err(e) => {
                    let backoff = self
                        .away
                        .as_ref()
                        .map_or(FIRST_BACKOFF, |a| (a.2 * 2).min(MAX_BACKOFF));
                    let why = reason(&e);
                    tracing::warn!(
                        "the job store at {} cannot be reached: {why}; trying again in {backoff:?}",
                        self.name
                    );
                    self.away = Some((why.clone(), Instant::now() + backoff, backoff));
                    return Err(Failure::Away(why));
                }
            }
        }
        Ok(self.client.as_mut().expect("connected above"))
    }

    /// The connection with its prepared statements.
    fn db(&mut self) -> Result<Db<'_>, Failure> {
        self.client()?;
        Ok(Db {
            client: self.client.as_mut().expect("connected above"),
            prepared: &mut self.prepared,
        })
    }
}

/// A driver error's own words (its Display hides the server's message behind "db error").
fn reason(e: &postgres::Error) -> String {
    match e.as_db_error() {
        Some(db) => format!("{}: {}", db.severity(), db.message()),
        None => e.to_string(),
    }
}

type Call = Box<dyn FnOnce(&mut Conn) + Send>;

/// The store: a handle on its thread.
pub(in crate::coordinator) struct PostgresStore {
    calls: mpsc::Sender<Call>,
    /// The server, as errors name it: host, port and database, never the password.
    name: String,
}

impl PostgresStore {
    /// Connects to the server at `url` (`postgres://user:password@host:port/database`)
    /// and brings its schema up to date. The server must answer now: a coordinator does
    /// not start on a store it has never reached.
    pub fn open(url: &str) -> Result<PostgresStore, StoreError> {
        let mut config: postgres::Config = url.parse().map_err(|e| {
            StoreError::new(format!(
                "--store: '{}' is not a PostgreSQL URL: {e}",
                redact(url)
            ))
        })?;
        config
            .connect_timeout(IO_TIMEOUT)
            .tcp_user_timeout(IO_TIMEOUT)
            .keepalives(true)
            .keepalives_idle(Duration::from_secs(5))
            .application_name("kiln coordinator");
        let name = describe(&config);
        let (calls, queue) = mpsc::channel::<Call>();
        let conn = Conn {
            config,
            name: name.clone(),
            client: None,
            away: None,
            fence: None,
            prepared: HashMap::new(),
        };
        std::thread::Builder::new()
            .name("kiln-store".into())
            .spawn(move || {
                let mut conn = conn;
                for call in queue {
                    // A call that panics (a row not of the schema's types) fails alone: its
                    // caller hears that the store stopped, and the thread serves the next.
                    let done =
                        std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| call(&mut conn)));
                    if done.is_err() {
                        tracing::error!("a job store call panicked; dropping its connection");
                        conn.client = None;
                        conn.prepared.clear();
                    }
                }
            })
            .map_err(|e| StoreError::new(format!("cannot start the job store's thread: {e}")))?;
        let store = PostgresStore { calls, name };
        let newer = store.call("upgrading the schema", |c| {
            let client = c.client()?;
            migrate(client)?;
            Ok(check_version(client)?)
        })?;
        newer.map_err(StoreError::new)?;
        Ok(store)
    }

    /// Runs `f` on the store's thread and waits for it.
    fn call<T: Send + 'static>(
        &self,
        doing: &str,
        f: impl FnOnce(&mut Conn) -> Result<T, Failure> + Send + 'static,
    ) -> Result<T, StoreError> {
        let (tx, rx) = mpsc::sync_channel(1);
        let call: Call = Box::new(move |conn: &mut Conn| {
            let out = f(conn);
            if let (Err(Failure::Db(_)), Some(c)) = (&out, &conn.client)
                && c.is_closed()
            {
                conn.client = None;
                conn.prepared.clear();
            }
            let _ = tx.send(out);
        });
        let gone = || StoreError::new(format!("the job store at {} has stopped", self.name));
        self.calls.send(call).map_err(|_| gone())?;
        let answer = rx.recv().map_err(|_| {
            StoreError::new(format!(
                "the job store at {}, {doing}: the call failed inside Kiln (the log has its panic)",
                self.name
            ))
        })?;
        match answer {
            Ok(v) => Ok(v),
            Err(Failure::Db(e)) => Err(StoreError::new(format!(
                "the job store at {}, {doing}: {}",
                self.name,
                reason(&e)
            ))),
            Err(Failure::Away(why)) => Err(StoreError::new(format!(
                "the job store at {} cannot be reached ({why}), {doing}",
                self.name
            ))),
            Err(Failure::Deposed(why)) => Err(StoreError::deposed(format!(
                "this coordinator no longer leads: {why}; {doing} refused"
            ))),
        }
    }

    /// Runs a statement or two on the store's thread (a write is fenced by the trigger).
    fn run<T: Send + 'static>(
        &self,
        doing: &str,
        f: impl FnOnce(&mut Db) -> Result<T, postgres::Error> + Send + 'static,
    ) -> Result<T, StoreError> {
        self.call(doing, move |c| Ok(f(&mut c.db()?)?))
    }

    /// Sets one of a job's notes.
    fn set_note(&self, job: u64, note: Note, value: i64) -> Result<(), StoreError> {
        self.run("keeping a job's note", move |db| {
            let sql = match note {
                Note::Verified => {
                    "INSERT INTO job_notes (job, verified) VALUES ($1, $2)
                     ON CONFLICT (job) DO UPDATE SET verified = $2"
                }
                Note::Webhook => {
                    "INSERT INTO job_notes (job, webhook) VALUES ($1, $2)
                     ON CONFLICT (job) DO UPDATE SET webhook = $2"
                }
            };
            db.execute(sql, &[&(job as i64), &value]).map(drop)
        })
    }

    /// One of a job's notes, 0 when it has none.
    fn note(&self, job: u64, note: Note) -> Result<i64, StoreError> {
        self.run("reading a job's note", move |db| {
            let sql = match note {
                Note::Verified => "SELECT verified FROM job_notes WHERE job = $1",
                Note::Webhook => "SELECT webhook FROM job_notes WHERE job = $1",
            };
            Ok(db.query_opt(sql, &[&(job as i64)])?.map_or(0, |r| r.get(0)))
        })
    }
}

/// A job's notes (columns of `job_notes`).
#[derive(Clone, Copy)]
enum Note {
    Verified,
    Webhook,
}

/// `postgres://user@host:port/db` with any password removed, for messages.
fn redact(url: &str) -> String {
    match (url.find("://"), url.rfind('@')) {
        (Some(s), Some(at)) if at > s => {
            let user = &url[s + 3..at];
            let user = user.split(':').next().unwrap_or("");
            format!("{}{user}@{}", &url[..s + 3], &url[at + 1..])
        }
        _ => url.to_string(),
    }
}

/// The server as messages name it: `host:port/database`.
fn describe(config: &postgres::Config) -> String {
    use postgres::config::Host;
    let host = match config.get_hosts().first() {
        Some(Host::Tcp(h)) => h.clone(),
        Some(Host::Unix(p)) => p.display().to_string(),
        None => "localhost".into(),
    };
    let port = config.get_ports().first().copied().unwrap_or(5432);
    let db = config
        .get_dbname()
        .or(config.get_user())
        .unwrap_or("postgres");
    format!("{host}:{port}/{db}")
}

/// Applies the migrations the store lacks, each with its version in one transaction, under
/// an advisory lock held by one coordinator at a time.
fn migrate(client: &mut Client) -> Result<(), postgres::Error> {
    client.batch_execute("CREATE TABLE IF NOT EXISTS kiln_schema (version INTEGER NOT NULL)")?;
    for m in MIGRATIONS {
        let mut tx = client.transaction()?;
        tx.execute("SELECT pg_advisory_xact_lock($1)", &[&MIGRATION_LOCK])?;
        let current: i32 = tx
            .query_opt("SELECT version FROM kiln_schema", &[])?
            .map_or(0, |r| r.get(0));
        if current >= m.version {
            continue;
        }
        tx.batch_execute(m.sql)?;
        tx.execute("DELETE FROM kiln_schema", &[])?;
        tx.execute(
            "INSERT INTO kiln_schema (version) VALUES ($1)",
            &[&m.version],
        )?;
        tx.commit()?;
    }
    Ok(())
}

/// The schema version of the store at the other end, checked after migrating: a newer
/// Kiln's store is refused rather than misread.
fn check_version(client: &mut Client) -> Result<Result<(), String>, postgres::Error> {
    let latest = MIGRATIONS.last().map_or(0, |m| m.version);
    let current: i32 = client
        .query_opt("SELECT version FROM kiln_schema", &[])?
        .map_or(0, |r| r.get(0));
    Ok(if current > latest {
        Err(format!(
            "the job store is at schema version {current}, written by a newer Kiln; this one knows versions up to {latest}"
        ))
    } else {
        Ok(())
    })
}

impl JobStore for PostgresStore {
    fn next_epoch(&self) -> Result<u64, StoreError> {
        self.run("counting this opening", |tx| {
            let epoch: i64 = tx
                .query_one(
                    "INSERT INTO meta (key, value) VALUES ('epoch', 1)
                     ON CONFLICT (key) DO UPDATE SET value = meta.value + 1
                     RETURNING value",
                    &[],
                )?
                .get(0);
            Ok(epoch as u64)
        })
    }

    fn jobs(&self) -> Result<Vec<StoredJob>, StoreError> {
        self.run("reading the jobs", |c| {
            let rows = c.query("SELECT id, spec, state, error FROM jobs ORDER BY id", &[])?;
            Ok(rows
                .iter()
                .map(|r| {
                    let spec: String = r.get(1);
                    let state: String = r.get(2);
                    StoredJob {
                        id: r.get::<_, i64>(0) as u64,
                        spec: serde_json::from_str(&spec)
                            .map_err(|e| format!("its record in the store is damaged: {e}")),
                        state: JobState::from_name(&state).unwrap_or(JobState::Failed),
                        error: r.get(3),
                    }
                })
                .collect())
        })
    }

    fn job_with_key(&self, key: &str) -> Result<Option<u64>, StoreError> {
        let key = key.to_string();
        self.run("finding a job by its key", move |c| {
            Ok(
                c.query_opt("SELECT id FROM jobs WHERE idempotency_key = $1", &[&key])?
                    .map(|r| r.get::<_, i64>(0) as u64),
            )
        })
    }

    fn insert_job(&self, spec: &JobSpec, key: Option<&str>) -> Result<u64, StoreError> {
        let spec_json = serde_json::to_string(spec).expect("a JobSpec serializes");
        let key = key.map(str::to_string);
        self.run("keeping a new job", move |tx| {
            let id: i64 = tx
                .query_one(
                    "INSERT INTO jobs (spec, state, idempotency_key) VALUES ($1, 'running', $2) RETURNING id",
                    &[&spec_json, &key],
                )?
                .get(0);
            Ok(id as u64)
        })
    }

    fn set_spec(&self, job: u64, spec: &JobSpec) -> Result<(), StoreError> {
        let spec_json = serde_json::to_string(spec).expect("a JobSpec serializes");
        self.run("keeping a job's spec", move |tx| {
            tx.execute(
                "UPDATE jobs SET spec = $1 WHERE id = $2",
                &[&spec_json, &(job as i64)],
            )
            .map(drop)
        })
    }

    fn set_state(&self, job: u64, state: JobState, error: Option<&str>) -> Result<(), StoreError> {
        let error = error.map(str::to_string);
        self.run("keeping a job's state", move |tx| {
            tx.execute(
                "UPDATE jobs SET state = $1, error = $2 WHERE id = $3",
                &[&state.as_str(), &error, &(job as i64)],
            )
            .map(drop)
        })
    }

    fn tiles(&self, job: u64, _legacy_samples: u32) -> Result<Vec<KeptTile>, StoreError> {
        self.run("reading a job's tiles", move |c| {
            let rows = c.query(
                "SELECT idx, samples, exr, unchecked_by FROM tile_passes WHERE job = $1",
                &[&(job as i64)],
            )?;
            Ok(rows
                .iter()
                .map(|r| KeptTile {
                    idx: r.get::<_, i64>(0) as usize,
                    samples: r.get::<_, i64>(1) as u32,
                    exr: r.get(2),
                    unchecked_by: serde_json::from_str(r.get::<_, &str>(3)).unwrap_or_default(),
                    legacy: false,
                })
                .collect())
        })
    }

    fn tile(&self, job: u64, idx: usize, samples: u32) -> Result<Option<Vec<u8>>, StoreError> {
        self.run("reading a tile", move |c| {
            Ok(c.query_opt(
                "SELECT exr FROM tile_passes WHERE job = $1 AND idx = $2 AND samples = $3",
                &[&(job as i64), &(idx as i64), &i64::from(samples)],
            )?
            .map(|r| r.get(0)))
        })
    }

    fn holds_tile(&self, job: u64, idx: usize, exr: &[u8]) -> Result<bool, StoreError> {
        let exr = exr.to_vec();
        self.run("comparing a tile", move |c| {
            Ok(c.query_opt(
                "SELECT 1 FROM tile_passes WHERE job = $1 AND idx = $2 AND exr = $3 LIMIT 1",
                &[&(job as i64), &(idx as i64), &exr],
            )?
            .is_some())
        })
    }

    fn insert_tile(
        &self,
        job: u64,
        idx: usize,
        samples: u32,
        exr: &[u8],
        unchecked_by: &BTreeSet<String>,
    ) -> Result<(), StoreError> {
        let by = serde_json::to_string(unchecked_by).expect("names serialize");
        let exr = exr.to_vec();
        self.run("keeping a tile", move |tx| {
            tx.execute(
                "INSERT INTO tile_passes (job, idx, samples, exr, unchecked_by) VALUES ($1, $2, $3, $4, $5)
                 ON CONFLICT DO NOTHING",
                &[&(job as i64), &(idx as i64), &i64::from(samples), &exr, &by],
            )
            .map(drop)
        })
    }

    fn drop_tiles(&self, job: u64, tiles: &[usize]) -> Result<(), StoreError> {
        let tiles: Vec<i64> = tiles.iter().map(|&t| t as i64).collect();
        self.run("forgetting tiles", move |tx| {
            tx.execute(
                "DELETE FROM tile_passes WHERE job = $1 AND idx = ANY($2)",
                &[&(job as i64), &tiles],
            )
            .map(drop)
        })
    }

    fn drop_passes_before(&self, job: u64, samples: u32) -> Result<(), StoreError> {
        self.run("forgetting earlier passes", move |tx| {
            tx.execute(
                "DELETE FROM tile_passes WHERE job = $1 AND samples < $2",
                &[&(job as i64), &i64::from(samples)],
            )
            .map(drop)
        })
    }

    fn add_verified(&self, job: u64) -> Result<(), StoreError> {
        self.run("counting a verified tile", move |tx| {
            tx.execute(
                "INSERT INTO job_notes (job, verified) VALUES ($1, 1)
                 ON CONFLICT (job) DO UPDATE SET verified = job_notes.verified + 1",
                &[&(job as i64)],
            )
            .map(drop)
        })
    }

    fn verified(&self, job: u64) -> Result<u64, StoreError> {
        Ok(self.note(job, Note::Verified)? as u64)
    }

    fn webhook(&self, job: u64) -> Result<WebhookOutcome, StoreError> {
        Ok(match self.note(job, Note::Webhook)? {
            1 => WebhookOutcome::Delivered,
            2 => WebhookOutcome::GaveUp,
            _ => WebhookOutcome::Pending,
        })
    }

    fn set_webhook(&self, job: u64, outcome: WebhookOutcome) -> Result<(), StoreError> {
        self.set_note(job, Note::Webhook, outcome as i64)
    }

    fn set_aside(&self, worker: &str, reason: &str) -> Result<(), StoreError> {
        let (worker, reason) = (worker.to_string(), reason.to_string());
        self.run("setting a worker aside", move |tx| {
            tx.execute(
                "INSERT INTO set_aside (worker, reason) VALUES ($1, $2) ON CONFLICT DO NOTHING",
                &[&worker, &reason],
            )
            .map(drop)
        })
    }

    fn reinstate(&self, worker: &str) -> Result<(), StoreError> {
        let worker = worker.to_string();
        self.run("reinstating a worker", move |tx| {
            tx.execute("DELETE FROM set_aside WHERE worker = $1", &[&worker])
                .map(drop)
        })
    }

    fn set_aside_workers(&self) -> Result<Vec<(String, String)>, StoreError> {
        self.run("reading the workers set aside", |c| {
            Ok(
                c.query("SELECT worker, reason FROM set_aside ORDER BY worker", &[])?
                    .iter()
                    .map(|r| (r.get(0), r.get(1)))
                    .collect(),
            )
        })
    }

    fn insert_token(&self, role: Role, name: &str, hash: &str) -> Result<u64, StoreError> {
        let (name, hash) = (name.to_string(), hash.to_string());
        self.run("keeping a token", move |tx| {
            let id: i64 = tx
                .query_one(
                    "INSERT INTO tokens (role, name, hash) VALUES ($1, $2, $3) RETURNING id",
                    &[&role.as_str(), &name, &hash],
                )?
                .get(0);
            Ok(id as u64)
        })
    }

    fn revoke_token(&self, id: u64) -> Result<bool, StoreError> {
        self.run("revoking a token", move |tx| {
            Ok(tx.execute(
                "UPDATE tokens SET revoked = true WHERE id = $1",
                &[&(id as i64)],
            )? > 0)
        })
    }

    fn tokens(&self) -> Result<Vec<StoredToken>, StoreError> {
        self.run("reading the tokens", |c| {
            let rows = c.query(
                "SELECT id, role, name, hash, revoked FROM tokens ORDER BY id",
                &[],
            )?;
            Ok(rows
                .iter()
                .filter_map(|r| {
                    // A role this Kiln does not know (a newer one's) grants nothing.
                    let role = match r.get::<_, &str>(1) {
                        "admin" => Role::Admin,
                        "submitter" => Role::Submitter,
                        "worker" => Role::Worker,
                        _ => return None,
                    };
                    Some(StoredToken {
                        id: r.get::<_, i64>(0) as u64,
                        role,
                        name: r.get(2),
                        hash: r.get(3),
                        revoked: r.get(4),
                    })
                })
                .collect())
        })
    }

    fn lead(&self, holder: &str, address: &str, ttl: Duration) -> Result<Leadership, StoreError> {
        let (holder, address) = (holder.to_string(), address.to_string());
        self.call("taking the lead", move |c| {
            let client = c.client()?;
            let taken = client.query_opt(
                "WITH before AS (SELECT holder, extract(epoch FROM now() - renewed)::float8 AS silent FROM leader WHERE id = 1)
                 INSERT INTO leader (id, holder, address, epoch, renewed) VALUES (1, $1, $2, 1, now())
                 ON CONFLICT (id) DO UPDATE SET holder = $1, address = $2, epoch = leader.epoch + 1, renewed = now()
                 WHERE leader.renewed < now() - make_interval(secs => $3)
                 RETURNING epoch, (SELECT holder FROM before), (SELECT silent FROM before)",
                &[&holder, &address, &ttl.as_secs_f64()],
            )?;
            if let Some(row) = taken {
                let epoch: i64 = row.get(0);
                // From now on every write on this connection (and any later one) is fenced.
                client.batch_execute(&format!("SET kiln.epoch = '{epoch}'"))?;
                c.fence = Some(epoch);
                let before: Option<String> = row.get(1);
                let silent: Option<f64> = row.get(2);
                return Ok(Leadership::Leading {
                    epoch: epoch as u64,
                    after: before.zip(silent),
                });
            }
            let row = client.query_one("SELECT holder, address, epoch FROM leader WHERE id = 1", &[])?;
            Ok(Leadership::Led {
                holder: row.get(0),
                address: row.get(1),
                epoch: row.get::<_, i64>(2) as u64,
            })
        })
    }

    fn renew_lead(&self) -> Result<bool, StoreError> {
        self.call("renewing the lead", |c| {
            let Some(epoch) = c.fence else {
                return Ok(true);
            };
            let n = c.client()?.execute(
                "UPDATE leader SET renewed = now() WHERE id = 1 AND epoch = $1",
                &[&epoch],
            )?;
            Ok(n == 1)
        })
    }

    fn resign_lead(&self) -> Result<(), StoreError> {
        self.call("giving up the lead", |c| {
            let Some(epoch) = c.fence.take() else {
                return Ok(());
            };
            c.client()?.execute(
                "UPDATE leader SET renewed = '-infinity' WHERE id = 1 AND epoch = $1",
                &[&epoch],
            )?;
            Ok(())
        })
    }
}

#[cfg(test)]
mod tests {
    use super::redact;

    #[test]
    fn a_url_is_shown_without_its_password() {
        assert_eq!(
            redact("postgres://kiln:s3cret@db:5432/farm"),
            "postgres://kiln@db:5432/farm"
        );
        assert_eq!(redact("postgres://db/farm"), "postgres://db/farm");
    }
}

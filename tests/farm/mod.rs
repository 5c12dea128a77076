//! The render farm with real processes and real sockets, by feature: merged images
//! bit-identical to `kiln render` (`bytes.rs`), surviving dead workers and a dead
//! coordinator (`failures.rs`), the HTTP API's refusals and answers (`api.rs`), its
//! connections under a crowd and hostile clients (`connections.rs`), progressive
//! passes (`passes.rs`), verified workers (`verify.rs`) and webhooks (`webhooks.rs`).
//!
//! Each test starts one [`Farm`]: a temporary folder, a coordinator (a process it can kill
//! and start again, or one in this process), the workers it asks for and a client. Every
//! wait is on a condition (a job's state, a line in a log, a count in the metrics) with a
//! limit, never a fixed sleep.

mod api;
mod bytes;
mod connections;
mod failures;
mod limits;
mod passes;
mod requirements;
mod roles;
mod shots;
mod tls;
mod verify;
mod webhooks;

use crate::util::{kiln, scene};
use kiln_farm::api::{JobSpec, JobState, JobStatus};
use kiln_farm::client::Client;
use kiln_farm::coordinator::{self, Config, Coordinator};
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Stdio};
use std::time::{Duration, Instant};

/// A farm rendered through `kiln farm` (a coordinator and workers it starts itself): the
/// merged EXR's bytes.
pub fn farm(scene_path: &Path, dir: &Path, name: &str, args: &[&str]) -> Vec<u8> {
    let out = dir.join(format!("{name}.exr"));
    let o = kiln()
        .arg("farm")
        .arg(scene_path)
        .arg("-o")
        .arg(&out)
        .arg("-q")
        .args(args)
        .output()
        .unwrap();
    assert!(
        o.status.success(),
        "kiln farm {args:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    std::fs::read(&out).unwrap()
}

/// Polls `ready` until it holds; panics after `limit`, saying `what` it waited for.
pub(crate) fn wait_for(what: &str, limit: Duration, mut ready: impl FnMut() -> bool) {
    let start = Instant::now();
    while !ready() {
        assert!(start.elapsed() < limit, "{what}: not within {limit:?}");
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// A child process that is killed when dropped, so a failing test leaves none behind.
pub(crate) struct Guard(Child);

impl Drop for Guard {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

impl std::ops::Deref for Guard {
    type Target = Child;
    fn deref(&self) -> &Child {
        &self.0
    }
}

impl std::ops::DerefMut for Guard {
    fn deref_mut(&mut self) -> &mut Child {
        &mut self.0
    }
}

/// A `kiln worker` process and its log.
pub(crate) struct Worker {
    pub child: Guard,
    pub log: PathBuf,
}

impl Worker {
    /// The log so far.
    pub fn text(&self) -> String {
        std::fs::read_to_string(&self.log).unwrap_or_default()
    }

    /// How many tiles it says it rendered.
    pub fn rendered(&self) -> usize {
        self.text()
            .lines()
            .filter(|l| l.contains("rendered job"))
            .count()
    }

    /// Waits until it has rendered `n` tiles.
    pub fn wait_rendered(&self, n: usize, limit: Duration) {
        wait_for(
            &format!("{} rendering {n} tiles", self.log.display()),
            limit,
            || self.rendered() >= n,
        );
    }

    /// Waits until its log holds `words`; returns the log.
    pub fn wait_for_log(&self, words: &str, limit: Duration) -> String {
        wait_for(
            &format!("'{words}' in {}", self.log.display()),
            limit,
            || self.text().contains(words),
        );
        self.text()
    }

    /// Sends it SIGTERM (through `kill`, where there is no signal API).
    pub fn sigterm(&self) {
        let term = std::process::Command::new("kill")
            .args(["-TERM", &self.child.id().to_string()])
            .status()
            .unwrap();
        assert!(term.success());
    }

    /// Waits for it to exit; panics after `limit`.
    pub fn wait_exit(&mut self, limit: Duration) -> std::process::ExitStatus {
        let mut status = None;
        wait_for("the worker's exit", limit, || {
            status = self.child.try_wait().unwrap();
            status.is_some()
        });
        status.unwrap()
    }

    /// Kills it (SIGKILL) and reaps it.
    pub fn kill(&mut self) {
        self.child.kill().unwrap();
        self.child.wait().unwrap();
    }
}

/// Where the coordinator runs.
enum Running {
    /// A `kiln coordinator` process on `port`, which the test may kill and start again.
    Process {
        child: Guard,
        port: u16,
    },
    /// An in-process coordinator serving until `stop` is sent.
    InProcess {
        stop: Option<tokio::sync::oneshot::Sender<()>>,
        server: Option<tokio::task::JoinHandle<std::io::Result<()>>>,
    },
    Stopped,
}

/// A farm for one test: a temporary folder (the coordinator's data directory, worker
/// caches and logs under it), a runtime, a coordinator, and a client of it.
pub(crate) struct Farm {
    // Dropped in this order: the coordinator stops, then its runtime, then the folder goes.
    running: Running,
    pub client: Client,
    pub rt: tokio::runtime::Runtime,
    pub url: String,
    token: Option<String>,
    pub dir: tempfile::TempDir,
}

impl Farm {
    /// A farm whose coordinator is a `kiln coordinator` process (leases of 1 s).
    pub fn process() -> Farm {
        Farm::process_with(|_| {})
    }

    /// As [`Farm::process`], with `prepare` given the data directory's path first (to
    /// mount something there, say).
    pub fn process_with(prepare: impl FnOnce(&Path)) -> Farm {
        Farm::process_in("", prepare)
    }

    /// A farm whose coordinator is a `kiln coordinator` process started after the shell
    /// limits `limits` (`ulimit -v 4000000`, say).
    pub fn process_under(limits: &str) -> Farm {
        Farm::process_in(limits, |_| {})
    }

    /// A coordinator process under the shell limits `limits`, its data directory handed to
    /// `prepare` first.
    fn process_in(limits: &str, prepare: impl FnOnce(&Path)) -> Farm {
        let dir = tempfile::tempdir().unwrap();
        prepare(&dir.path().join("data"));
        let port = free_port();
        let child = start_coordinator_under(limits, &dir.path().join("data"), port);
        Farm::new(
            dir,
            tokio::runtime::Runtime::new().unwrap(),
            format!("http://127.0.0.1:{port}"),
            None,
            Running::Process { child, port },
        )
    }

    /// The coordinator process's id (a farm whose coordinator is a process).
    pub fn coordinator_pid(&self) -> u32 {
        match &self.running {
            Running::Process { child, .. } => child.id(),
            _ => panic!("the coordinator runs in this process"),
        }
    }

    /// A farm whose coordinator runs in this process, with `token` if given.
    pub fn in_process(token: Option<&str>) -> Farm {
        Farm::configured(token, |_| {})
    }

    /// As [`Farm::in_process`], with the coordinator's configuration changed by `change`.
    pub fn configured(token: Option<&str>, change: impl Fn(&mut Config)) -> Farm {
        let dir = tempfile::tempdir().unwrap();
        let rt = tokio::runtime::Runtime::new().unwrap();
        let (url, running) = serve(&rt, &dir.path().join("data"), token, &change);
        Farm::new(dir, rt, url, token.map(String::from), running)
    }

    fn new(
        dir: tempfile::TempDir,
        rt: tokio::runtime::Runtime,
        url: String,
        token: Option<String>,
        running: Running,
    ) -> Farm {
        Farm {
            running,
            client: Client::new(&url, token.clone()),
            rt,
            url,
            token,
            dir,
        }
    }

    /// A path in the farm's folder.
    pub fn path(&self, name: &str) -> PathBuf {
        self.dir.path().join(name)
    }

    /// The coordinator's data directory.
    pub fn data(&self) -> PathBuf {
        self.path("data")
    }

    /// Kills (SIGKILL) the coordinator process and reaps it.
    pub fn kill_coordinator(&mut self) {
        match &mut self.running {
            Running::Process { child, .. } => {
                child.kill().unwrap();
                child.wait().unwrap();
            }
            _ => panic!("only a coordinator process can be killed"),
        }
    }

    /// Starts the coordinator process again, on its port and data directory.
    pub fn start_coordinator(&mut self) {
        let Running::Process { port, .. } = self.running else {
            panic!("only a coordinator process is started again");
        };
        let child = start_coordinator_process(&self.data(), port);
        self.running = Running::Process { child, port };
    }

    /// Stops the in-process coordinator gracefully (its server returns), and starts another
    /// on the same data directory with `change` made to its configuration; the farm's URL
    /// and client are the new one's.
    pub fn restart_in_process(&mut self, change: impl Fn(&mut Config)) {
        let Running::InProcess { stop, server } = &mut self.running else {
            panic!("not an in-process coordinator");
        };
        stop.take().unwrap().send(()).unwrap();
        self.rt.block_on(server.take().unwrap()).unwrap().unwrap();
        self.running = Running::Stopped;
        let (url, running) = serve(&self.rt, &self.data(), self.token.as_deref(), &change);
        self.client = Client::new(&url, self.token.clone());
        self.url = url;
        self.running = running;
    }

    /// A one-thread `kiln worker` named `name`, with a cache and log of its own.
    pub fn worker(&self, name: &str) -> Worker {
        self.worker_with(name, &format!("cache-{name}"), &[])
    }

    /// A one-thread `kiln worker` named `name` with the cache folder `cache` and `extra`
    /// arguments (the farm's token is passed on).
    pub fn worker_with(&self, name: &str, cache: &str, extra: &[&str]) -> Worker {
        let log = self.path(&format!("{name}.log"));
        let mut args: Vec<&str> = extra.to_vec();
        if let Some(t) = &self.token {
            args.extend(["--token", t]);
        }
        Worker {
            child: start_worker_with(&self.url, name, &self.path(cache), &log, &args),
            log,
        }
    }

    /// `kiln submit` of `scene_path` with `args`; returns the job's id.
    pub fn submit(&self, scene_path: &Path, args: &[&str]) -> u64 {
        let o = kiln()
            .arg("submit")
            .arg(scene_path)
            .args(["--coordinator", &self.url])
            .args(args)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        String::from_utf8_lossy(&o.stdout)
            .trim()
            .rsplit(' ')
            .next()
            .unwrap()
            .parse()
            .unwrap()
    }

    /// Uploads the scene at `scene_path` as a bundle; returns its digest.
    pub fn upload(&self, scene_path: &Path) -> String {
        let bundle = kiln_farm::bundle::pack(scene_path).unwrap();
        self.rt
            .block_on(self.client.upload_scene(bundle.bytes))
            .unwrap()
    }

    /// A job spec for the scene `digest` with Kiln's defaults (tiles of 32, one pass).
    pub fn spec(digest: &str) -> JobSpec {
        JobSpec::new(digest)
    }

    /// Creates a job; returns its id.
    pub fn create(&self, spec: &JobSpec) -> u64 {
        self.rt
            .block_on(self.client.create_job(spec, None))
            .unwrap()
    }

    /// Uploads one of the repository's scenes and creates a job for it.
    pub fn job(
        &self,
        scene_file: &str,
        spp: Option<u32>,
        resolution: Option<(u32, u32)>,
        tile: u32,
    ) -> u64 {
        let spec = JobSpec {
            spp,
            resolution,
            tile,
            ..Farm::spec(&self.upload(&scene(scene_file)))
        };
        self.create(&spec)
    }

    /// The job's status.
    pub fn status(&self, id: u64) -> JobStatus {
        self.rt.block_on(self.client.status(id)).unwrap()
    }

    /// Waits until the job is no longer running; returns its status.
    pub fn wait_done(&self, id: u64, limit: Duration) -> JobStatus {
        let mut last = None;
        wait_for(&format!("job {id} ending"), limit, || {
            last = self
                .rt
                .block_on(self.client.status(id))
                .ok()
                .filter(|s| s.state != JobState::Running);
            last.is_some()
        });
        last.unwrap()
    }

    /// The job's merged EXR.
    pub fn result(&self, id: u64) -> Vec<u8> {
        self.rt.block_on(self.client.result(id)).unwrap()
    }

    /// Waits until the coordinator has issued `n` leases (its metrics say so).
    pub fn wait_for_leases(&self, n: u64) {
        let want = format!("kiln_leases_issued_total {n}");
        wait_for(&format!("lease {n}"), Duration::from_secs(30), || {
            let text = self
                .rt
                .block_on(async {
                    reqwest::get(format!("{}/metrics", self.url))
                        .await?
                        .text()
                        .await
                })
                .unwrap_or_default();
            text.lines().any(|l| l.trim() == want)
        });
    }
}

pub(crate) fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

/// A `kiln coordinator` process on `port` with leases of 1 s, once it says it listens.
fn start_coordinator_process(data: &Path, port: u16) -> Guard {
    start_coordinator_under("", data, port)
}

/// As [`start_coordinator_process`], started by bash after `limits` (`ulimit -v 4000000`,
/// say; nothing if empty).
pub(crate) fn start_coordinator_under(limits: &str, data: &Path, port: u16) -> Guard {
    let mut cmd = std::process::Command::new("bash");
    cmd.args(["-c", &format!("{limits}\nexec \"$@\""), "bash"])
        .arg(kiln().get_program())
        .args([
            "coordinator",
            "--listen",
            &format!("127.0.0.1:{port}"),
            "--lease-ttl",
            "1",
        ])
        .arg("--data-dir")
        .arg(data)
        .stderr(Stdio::null());
    listening(&mut cmd).0
}

/// Starts `cmd`, a `kiln coordinator`, once it says it listens: the process, and the URL it
/// gave.
pub(crate) fn listening(cmd: &mut std::process::Command) -> (Guard, String) {
    let mut child = cmd
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    let mut line = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut line)
        .unwrap();
    assert!(line.contains("listening on"), "{line}");
    let url = line
        .split_whitespace()
        .find(|w| w.starts_with("http"))
        .unwrap_or_default()
        .to_string();
    (Guard(child), url)
}

/// A coordinator in this process on a free port, on `rt`.
fn serve(
    rt: &tokio::runtime::Runtime,
    data: &Path,
    token: Option<&str>,
    change: &dyn Fn(&mut Config),
) -> (String, Running) {
    let mut config = Config::new(data.to_path_buf());
    config.token = token.map(String::from);
    change(&mut config);
    let c = Coordinator::open(config).unwrap();
    let listener = rt
        .block_on(tokio::net::TcpListener::bind("127.0.0.1:0"))
        .unwrap();
    let url = format!("http://{}", listener.local_addr().unwrap());
    let (stop, stopped) = tokio::sync::oneshot::channel::<()>();
    let server = rt.spawn(coordinator::serve(listener, c, async move {
        let _ = stopped.await;
    }));
    let running = Running::InProcess {
        stop: Some(stop),
        server: Some(server),
    };
    (url, running)
}

/// A one-thread `kiln worker` named `name`, with `extra` arguments, logging to `log`.
pub(crate) fn start_worker_with(
    url: &str,
    name: &str,
    cache: &Path,
    log: &Path,
    extra: &[&str],
) -> Guard {
    Guard(
        kiln()
            .args([
                "worker",
                "--coordinator",
                url,
                "--threads",
                "1",
                "--name",
                name,
            ])
            .args(extra)
            .arg("--cache-dir")
            .arg(cache)
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(std::fs::File::create(log).unwrap())
            .spawn()
            .unwrap(),
    )
}

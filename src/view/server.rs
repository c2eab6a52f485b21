//! The HTTP side of `ipfn view`: axum answers the page, the run and cached tiles at once;
//! tiles not yet painted wait in a render queue that a few render threads serve newest first,
//! so panning never waits behind tiles that scrolled out of sight. A tile whose request was
//! abandoned (the browser moved on) is not painted; a full queue answers its oldest request 503
//! (the page retries) instead of growing.
//!
//! Routes (nothing else; no route reads a path from a request): `/` the page, `/api/info`,
//! `/api/run`, `/tile?…`, `/preview/iter-N.png`, `POST /export?…`, `/exports/NAME` (only files
//! this server wrote).

use std::collections::{HashMap, HashSet, VecDeque};
use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::time::Duration;

use axum::extract::{Path, RawQuery, Request, State};
use axum::http::{Method, StatusCode, header};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use serde_json::json;
use tokio::sync::oneshot;

mod export;

use super::{ModelSource, View, ViewModel, parse_query, position};
use crate::error::{Error, Result};
use export::{export, exported};

/// Runs `ipfn synth` with these arguments (those after `synth`): how exports are written.
pub type Exporter = Box<dyn Fn(&[String]) -> Result<()> + Send + Sync>;

/// The server's limits and where it writes.
pub struct ServerConfig {
    /// Threads that render tiles (each render also uses the CPU evaluator's threads).
    pub render_threads: usize,
    /// Tile requests waiting at most; beyond, the oldest is answered 503.
    pub queue: usize,
    /// Bytes of encoded tiles kept.
    pub cache_bytes: usize,
    /// Where exports are written.
    pub export_dir: PathBuf,
}

impl Default for ServerConfig {
    fn default() -> Self {
        Self {
            render_threads: std::thread::available_parallelism().map_or(2, |n| n.get().min(4)),
            queue: 64,
            cache_bytes: 256 << 20,
            export_dir: PathBuf::from("."),
        }
    }
}

impl ServerConfig {
    /// The defaults with the user's cache size (in MiB) and export folder, both checked.
    pub fn new(cache_mb: usize, export_dir: PathBuf) -> Result<Self> {
        if !export_dir.is_dir() {
            return Err(crate::setting_error!(
                "--export-dir",
                export_dir.display(),
                "no such folder"
            ));
        }
        if cache_mb == 0 || cache_mb > 1 << 20 {
            return Err(crate::setting_error!(
                "--cache-mb",
                cache_mb,
                "give 1 to 1048576"
            ));
        }
        Ok(Self {
            cache_bytes: cache_mb << 20,
            export_dir,
            ..Self::default()
        })
    }
}

/// A tile asked for: the model and view, its top-left pixel and side, and its cache key.
struct TileAsk {
    model: Arc<ViewModel>,
    view: View,
    at: [i64; 2],
    side: usize,
    key: String,
}

/// A tile waiting for a render thread, and where its PNG goes.
struct Job {
    ask: TileAsk,
    reply: oneshot::Sender<Result<Arc<Vec<u8>>>>,
}

/// Encoded tiles, least recently used first out, bounded in bytes.
#[derive(Default)]
struct TileCache {
    tiles: HashMap<String, (Arc<Vec<u8>>, u64)>,
    bytes: usize,
    clock: u64,
}

impl TileCache {
    fn get(&mut self, key: &str) -> Option<Arc<Vec<u8>>> {
        self.clock += 1;
        let clock = self.clock;
        self.tiles.get_mut(key).map(|(png, used)| {
            *used = clock;
            png.clone()
        })
    }

    fn insert(&mut self, key: String, png: Arc<Vec<u8>>, budget: usize) {
        self.clock += 1;
        self.bytes += png.len();
        if let Some((old, _)) = self.tiles.insert(key, (png, self.clock)) {
            self.bytes -= old.len();
        }
        while self.bytes > budget {
            let oldest = self.tiles.iter().min_by_key(|(_, (_, used))| *used);
            let Some(oldest) = oldest.map(|(k, _)| k.clone()) else {
                break;
            };
            if let Some((png, _)) = self.tiles.remove(&oldest) {
                self.bytes -= png.len();
            }
        }
    }
}

/// Counters shown by `/api/info` (and used by the load test).
#[derive(Default)]
struct Counters {
    rendered: AtomicU64,
    cached: AtomicU64,
    busy: AtomicU64,
    abandoned: AtomicU64,
    rendering: AtomicU64,
}

struct Shared {
    /// The `Host` values a request may carry (None: any, when told to listen beyond loopback).
    hosts: Option<Vec<String>>,
    source: ModelSource,
    run_dir: Option<PathBuf>,
    config: ServerConfig,
    exporter: Exporter,
    cache: Mutex<TileCache>,
    queue: Mutex<VecDeque<Job>>,
    work: Condvar,
    export: Mutex<()>,
    exports: Mutex<HashSet<String>>,
    counters: Counters,
}

/// A bound `ipfn view` server; [`ViewServer::serve`] answers requests until `stop` is raised.
pub struct ViewServer {
    listener: std::net::TcpListener,
    shared: Arc<Shared>,
}

fn with_type(
    status: StatusCode,
    kind: &'static str,
    cache: &'static str,
    body: Vec<u8>,
) -> Response {
    let headers = [
        (header::CONTENT_TYPE, kind),
        (header::X_CONTENT_TYPE_OPTIONS, "nosniff"),
        (header::CACHE_CONTROL, cache),
    ];
    (status, headers, body).into_response()
}

fn text(status: StatusCode, message: &str) -> Response {
    with_type(
        status,
        "text/plain; charset=utf-8",
        "no-store",
        format!("{message}\n").into_bytes(),
    )
}

fn json_reply(value: &serde_json::Value) -> Response {
    with_type(
        StatusCode::OK,
        "application/json",
        "no-store",
        value.to_string().into_bytes(),
    )
}

fn png_reply(png: &[u8]) -> Response {
    with_type(
        StatusCode::OK,
        "image/png",
        "private, max-age=3600",
        png.to_vec(),
    )
}

fn error_reply(e: &Error) -> Response {
    match e {
        e if e.is_input() => text(StatusCode::BAD_REQUEST, &e.to_string()),
        _ => text(StatusCode::INTERNAL_SERVER_ERROR, &e.to_string()),
    }
}

/// The names a route accepts; any other is refused, so a typo is not silently ignored.
fn only(q: &HashMap<String, String>, names: &[&str]) -> Result<()> {
    match q.keys().find(|k| !names.contains(&k.as_str())) {
        Some(k) => Err(crate::input_error!(
            "unknown parameter '{}'",
            k.chars().take(32).collect::<String>()
        )),
        None => Ok(()),
    }
}

const VIEW_PARAMS: [&str; 10] = [
    "seed", "zoom", "noise", "tile", "guide", "frame", "density", "map", "axis", "depth",
];

impl ViewServer {
    /// Binds `addr` (port 0: a free port) to serve `source`, and the run in `run_dir` if given.
    pub fn bind(
        addr: SocketAddr,
        source: ModelSource,
        run_dir: Option<PathBuf>,
        config: ServerConfig,
        exporter: Exporter,
    ) -> Result<Self> {
        let listener = std::net::TcpListener::bind(addr)
            .and_then(|l| l.set_nonblocking(true).map(|_| l))
            .map_err(|e| {
                crate::input_error!("cannot listen on {addr}: {e}; choose another --port")
            })?;
        let port = listener.local_addr().map(|a| a.port()).unwrap_or(0);
        let bound = match addr.ip() {
            std::net::IpAddr::V6(ip) => format!("[{ip}]"),
            ip => ip.to_string(),
        };
        let hosts = addr.ip().is_loopback().then(|| {
            [bound.as_str(), "127.0.0.1", "localhost", "[::1]"]
                .iter()
                .map(|h| format!("{h}:{port}"))
                .collect()
        });
        let shared = Shared {
            hosts,
            source,
            run_dir,
            config,
            exporter,
            cache: Mutex::default(),
            queue: Mutex::default(),
            work: Condvar::new(),
            export: Mutex::new(()),
            exports: Mutex::default(),
            counters: Counters::default(),
        };
        Ok(Self {
            listener,
            shared: Arc::new(shared),
        })
    }

    /// The address bound.
    pub fn addr(&self) -> SocketAddr {
        self.listener.local_addr().expect("a bound listener")
    }

    /// Answers requests until `stop` is raised.
    pub fn serve(self, stop: &'static AtomicBool) -> Result<()> {
        let runtime = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(2)
            .enable_io()
            .enable_time()
            .build()
            .map_err(|e| Error::Runtime(format!("cannot start the server: {e}")))?;
        let app = axum::Router::new()
            .route("/", get(page))
            .route("/api/info", get(info))
            .route("/api/run", get(run))
            .route("/tile", get(tile))
            .route("/export", post(export))
            .route("/preview/{name}", get(preview))
            .route("/exports/{name}", get(exported))
            .fallback(|| async { text(StatusCode::NOT_FOUND, "no such page; the viewer is at /") })
            .method_not_allowed_fallback(|| async {
                text(StatusCode::METHOD_NOT_ALLOWED, "method not allowed")
            })
            .layer(axum::middleware::from_fn_with_state(
                self.shared.clone(),
                guard,
            ))
            .with_state(self.shared.clone());
        std::thread::scope(|scope| {
            for _ in 0..self.shared.config.render_threads.max(1) {
                scope.spawn(|| render_loop(&self.shared, stop));
            }
            let served = runtime.block_on(async {
                let listener = tokio::net::TcpListener::from_std(self.listener)?;
                axum::serve(listener, app)
                    .with_graceful_shutdown(async move {
                        while !stop.load(Ordering::SeqCst) {
                            tokio::time::sleep(Duration::from_millis(200)).await;
                        }
                    })
                    .await
            });
            stop.store(true, Ordering::SeqCst);
            self.shared.work.notify_all();
            // Waiting requests are answered (503) as their jobs are dropped.
            self.shared
                .queue
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .clear();
            served.map_err(|e| Error::Runtime(format!("the server stopped: {e}")))
        })
    }
}

/// Renders queued tiles, newest first, until `stop`; skips tiles nobody waits for any more.
fn render_loop(shared: &Shared, stop: &AtomicBool) {
    while !stop.load(Ordering::SeqCst) {
        let job = {
            let mut queue = shared.queue.lock().expect("queue lock");
            match queue.pop_back() {
                Some(job) => job,
                None => {
                    let _ = shared.work.wait_timeout(queue, Duration::from_millis(200));
                    continue;
                }
            }
        };
        if job.reply.is_closed() {
            shared.counters.abandoned.fetch_add(1, Ordering::Relaxed);
            continue;
        }
        let Job { ask, reply } = job;
        let cached = shared.cache.lock().expect("cache lock").get(&ask.key);
        let png = match cached {
            Some(png) => Ok(png),
            None => {
                shared.counters.rendering.fetch_add(1, Ordering::SeqCst);
                let size = [ask.side, ask.side];
                // A failing device (out of memory, lost) answers 500, and the thread lives on.
                let painted = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                    ask.model.tile_png(&ask.view, ask.at, size)
                }));
                let png = painted
                    .unwrap_or_else(|_| Err(Error::Runtime("the tile's render failed".into())))
                    .map(Arc::new);
                shared.counters.rendering.fetch_sub(1, Ordering::SeqCst);
                if let Ok(png) = &png {
                    shared.counters.rendered.fetch_add(1, Ordering::Relaxed);
                    let budget = shared.config.cache_bytes;
                    shared
                        .cache
                        .lock()
                        .expect("cache lock")
                        .insert(ask.key, png.clone(), budget);
                }
                png
            }
        };
        let _ = reply.send(png);
    }
}

type SharedState = State<Arc<Shared>>;

/// The page as served: the script in place, no embedded run data.
async fn page() -> Response {
    let html = super::PAGE_HTML
        .replace("/*IPFN_DATA*/", "")
        .replace("/*IPFN_SCRIPT*/", super::PAGE_JS);
    with_type(
        StatusCode::OK,
        "text/html; charset=utf-8",
        "no-store",
        html.into_bytes(),
    )
}

/// The model now, read off the async runtime's threads (a reload parses a checkpoint).
async fn current_model(shared: &Arc<Shared>) -> Result<Option<Arc<ViewModel>>> {
    let shared = shared.clone();
    tokio::task::spawn_blocking(move || shared.source.current())
        .await
        .unwrap_or_else(|e| Err(Error::Runtime(format!("loading the model: {e}"))))
}

/// Every request: its `Host` must be this server's loopback address (so a web page elsewhere
/// cannot reach it by DNS rebinding), and a POST must carry `X-Ipfn: 1`, which a cross-site form
/// or simple request cannot send.
async fn guard(State(shared): SharedState, request: Request, next: Next) -> Response {
    let host = request
        .headers()
        .get(header::HOST)
        .and_then(|h| h.to_str().ok());
    if let Some(hosts) = &shared.hosts
        && !host.is_some_and(|h| hosts.iter().any(|a| a == h))
    {
        return text(
            StatusCode::FORBIDDEN,
            "this server answers its own address only",
        );
    }
    if request.method() == Method::POST && request.headers().get("x-ipfn").is_none() {
        return text(
            StatusCode::FORBIDDEN,
            "POST needs the header X-Ipfn: 1 (the page sends it)",
        );
    }
    next.run(request).await
}

async fn info(State(shared): SharedState) -> Response {
    let model = match current_model(&shared).await {
        Ok(model) => model,
        Err(e) => return error_reply(&e),
    };
    let queued = shared.queue.lock().expect("queue lock").len();
    let c = &shared.counters;
    json_reply(&json!({
        "model": model.map(|m| m.info()),
        "run": shared.run_dir.as_ref().map(|d| d.display().to_string()),
        "queued": queued,
        "rendering": c.rendering.load(Ordering::SeqCst),
        "rendered": c.rendered.load(Ordering::Relaxed),
        "cached": c.cached.load(Ordering::Relaxed),
        "busy": c.busy.load(Ordering::Relaxed),
        "abandoned": c.abandoned.load(Ordering::Relaxed),
        "cache_bytes": shared.cache.lock().expect("cache lock").bytes,
    }))
}

async fn run(State(shared): SharedState) -> Response {
    match &shared.run_dir {
        Some(dir) => {
            let dir = dir.clone();
            let snapshot = tokio::task::spawn_blocking(move || crate::report::snapshot(&dir)).await;
            match snapshot {
                Ok(snapshot) => json_reply(&snapshot),
                Err(e) => text(StatusCode::INTERNAL_SERVER_ERROR, &e.to_string()),
            }
        }
        None => text(
            StatusCode::NOT_FOUND,
            "this view shows a model file, not a run folder",
        ),
    }
}

/// What a tile request asks for, checked.
fn tile_job(model: Option<Arc<ViewModel>>, query: &str) -> Result<TileAsk> {
    let q = parse_query(query)?;
    only(&q, &[&VIEW_PARAMS[..], &["x", "y", "size", "v"]].concat())?;
    let model = model.ok_or_else(|| {
        crate::input_error!("the run has no checkpoint yet; tiles appear after its first")
    })?;
    let view = View::from_query(&q, &model)?;
    let side: usize = super::param(&q, "size")?.unwrap_or(256);
    if !super::TILE_SIDES.contains(&side) {
        return Err(crate::input_error!(
            "size {side}: a tile's side is 16 to 1024 pixels"
        ));
    }
    let at = [position(&q, "x")?, position(&q, "y")?];
    let key = format!("{}|{view:?}|{at:?}|{side}", model.version);
    Ok(TileAsk {
        model,
        view,
        at,
        side,
        key,
    })
}

/// `/tile?x=&y=&size=&…view…`: from the cache, or painted by a render thread.
async fn tile(State(shared): SharedState, RawQuery(query): RawQuery) -> Response {
    let model = match current_model(&shared).await {
        Ok(model) => model,
        Err(e) => return error_reply(&e),
    };
    let ask = match tile_job(model, query.as_deref().unwrap_or("")) {
        Ok(ask) => ask,
        Err(e) => return error_reply(&e),
    };
    let hit = shared.cache.lock().expect("cache lock").get(&ask.key);
    if let Some(png) = hit {
        shared.counters.cached.fetch_add(1, Ordering::Relaxed);
        return png_reply(&png);
    }
    let (reply, painted) = oneshot::channel();
    {
        let mut queue = shared.queue.lock().expect("queue lock");
        queue.push_back(Job { ask, reply });
        if queue.len() > shared.config.queue {
            // Dropping the oldest job's sender answers its request 503 below.
            queue.pop_front();
            shared.counters.busy.fetch_add(1, Ordering::Relaxed);
        }
    }
    shared.work.notify_one();
    match painted.await {
        Ok(Ok(png)) => png_reply(&png),
        Ok(Err(e)) => error_reply(&e),
        Err(_) => text(
            StatusCode::SERVICE_UNAVAILABLE,
            "busy: newer tiles were asked for; retry",
        ),
    }
}

/// `/preview/iter-N.png`: a preview of the run, by name only.
async fn preview(State(shared): SharedState, Path(name): Path<String>) -> Response {
    let Some(dir) = &shared.run_dir else {
        return text(StatusCode::NOT_FOUND, "no run folder");
    };
    if !crate::report::is_preview_name(&name) {
        return text(StatusCode::NOT_FOUND, "no such preview");
    }
    match std::fs::read(dir.join("previews").join(&name)) {
        Ok(bytes) => png_reply(&bytes),
        Err(_) => text(StatusCode::NOT_FOUND, "no such preview"),
    }
}

//! The listener and its connections. The socket is bound by the caller's
//! thread (so a busy port or a refused address stops `morphoid run` with
//! a clear error), then served on a multi-thread tokio runtime of the
//! server's own, on a thread of its own (why: see the module `http`).
//!
//! Connections are served by hyper's HTTP/1 connection builder, which
//! bounds what a client can hold: the request head's size
//! (`max_header_bytes`) and the time to send it (`header_timeout_seconds`,
//! against slow clients); at most `max_connections` at once. Each request
//! has `request_timeout_seconds` and a body of at most `max_body_bytes`
//! (tower-http), and every response says `nosniff`, no framing and no
//! referrer.

use super::state::AppState;
use super::status::LiveStatus;
use super::{api, metrics, openapi, pages};
use crate::config::{Config, Http};
use crate::store::{Store, StoreError};
use axum::extract::DefaultBodyLimit;
use axum::http::{header, HeaderValue, Request, StatusCode};
use axum::routing::{get, post};
use axum::Router;
use hyper::body::Incoming;
use hyper_util::rt::{TokioIo, TokioTimer};
use hyper_util::service::TowerToHyperService;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;
use tokio::sync::{watch, Semaphore};
use tokio_rustls::TlsAcceptor;
use tower::ServiceExt as _;
use tower_http::limit::RequestBodyLimitLayer;
use tower_http::set_header::SetResponseHeaderLayer;
use tower_http::timeout::TimeoutLayer;

/// Worker threads of the server's runtime: requests mostly wait for
/// SQLite (on the blocking pool), so two are plenty on a lab server.
const WORKER_THREADS: usize = 2;

/// Blocking threads (database reads, password checks) at most.
const BLOCKING_THREADS: usize = 8;

/// How long a stop waits for requests in progress.
const STOP_GRACE: Duration = Duration::from_secs(2);

/// The client address of a request's connection (a request extension).
#[derive(Debug, Clone, Copy)]
pub(super) struct PeerAddr(pub SocketAddr);

/// Why the server could not start.
#[derive(Debug, thiserror::Error)]
pub enum HttpError {
    /// `[http] listen` is not an address and port.
    #[error(transparent)]
    Listen(crate::config::ValueError),
    /// A non-loopback address without any curator to log in.
    #[error(
        "refusing to serve on {addr}: an address other than loopback needs authentication; \
         add a user first (morphoid user add NAME) or listen on 127.0.0.1"
    )]
    NoCurators {
        /// The configured address.
        addr: SocketAddr,
    },
    /// The address cannot be bound (in use, not this machine's).
    #[error("cannot listen on {addr}")]
    Bind {
        /// The configured address.
        addr: SocketAddr,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// The certificate or key of `[http] tls_cert`/`tls_key` is unusable.
    #[error("cannot serve HTTPS with {}: {message}", path.display())]
    Tls {
        /// The certificate or key file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// The database cannot be opened to check for curators.
    #[error("the web console cannot read the database")]
    Store(#[from] StoreError),
    /// The runtime or the thread could not be started.
    #[error("cannot start the web console's {what}")]
    Start {
        /// What.
        what: &'static str,
        /// Why.
        #[source]
        source: std::io::Error,
    },
}

/// What the console serves: the daemon's database and library, and what
/// the daemon tells it.
#[derive(Debug, Clone)]
pub struct Sources {
    /// The database file.
    pub db: PathBuf,
    /// The library folder.
    pub library: PathBuf,
    /// The library's ranks, broadest first (empty: any).
    pub ranks: Vec<String>,
    /// The daemon's snapshot, and its reload requests.
    pub live: LiveStatus,
}

impl Sources {
    /// The database and library of `config`.
    pub fn of(config: &Config, live: LiveStatus) -> Self {
        Sources {
            db: config.database.path.clone(),
            library: config.library.dir.clone(),
            ranks: config.library.ranks.clone(),
            live,
        }
    }
}

/// Whether serving on `addr` needs at least one curator: every address but
/// loopback does (an IPv4-mapped loopback address counts as another).
pub(crate) fn requires_curators(addr: &SocketAddr) -> bool {
    !addr.ip().is_loopback()
}

/// A running server; stopped when dropped.
#[derive(Debug)]
pub struct Server {
    addr: SocketAddr,
    stop: watch::Sender<bool>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl Server {
    /// Start the server that `settings` configures (`None`: `listen` is not
    /// set) on `sources`.
    pub fn start_configured(
        settings: &Http,
        sources: Sources,
    ) -> Result<Option<Server>, HttpError> {
        match settings.listen_addr().map_err(HttpError::Listen)? {
            Some(addr) => Server::start(addr, settings, sources).map(Some),
            None => Ok(None),
        }
    }

    /// Start serving on `addr` (port 0: any free port; see
    /// [`Server::local_addr`]).
    pub fn start(addr: SocketAddr, settings: &Http, sources: Sources) -> Result<Server, HttpError> {
        if requires_curators(&addr) && Store::open(&sources.db)?.curator_count()? == 0 {
            return Err(HttpError::NoCurators { addr });
        }
        let listener =
            std::net::TcpListener::bind(addr).map_err(|source| HttpError::Bind { addr, source })?;
        listener
            .set_nonblocking(true)
            .map_err(|source| HttpError::Bind { addr, source })?;
        let local = listener
            .local_addr()
            .map_err(|source| HttpError::Bind { addr, source })?;
        let priority = crate::priority::ConsolePriority::start();
        let leaving = priority.clone();
        let runtime = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(WORKER_THREADS)
            .max_blocking_threads(BLOCKING_THREADS)
            .thread_name("morphoid-http")
            .on_thread_start(move || priority.enter())
            .on_thread_stop(move || leaving.leave())
            .enable_all()
            .build()
            .map_err(|source| HttpError::Start {
                what: "async runtime",
                source,
            })?;
        let listener = {
            let _in_runtime = runtime.enter();
            tokio::net::TcpListener::from_std(listener)
                .map_err(|source| HttpError::Bind { addr, source })?
        };
        let tls = tls_acceptor(settings)?;
        let mut state = AppState::new(settings, sources);
        state.secure_cookies = tls.is_some();
        let app = router(Arc::new(state));
        let secure = tls.is_some();
        let (stop, stopped) = watch::channel(false);
        let limits = Limits::of(settings);
        let thread = std::thread::Builder::new()
            .name("morphoid-http-accept".into())
            .spawn(move || {
                runtime.block_on(accept_loop(listener, app, tls, limits, stopped));
                // Requests still running when the grace is over are dropped.
                runtime.shutdown_timeout(Duration::from_millis(500));
            })
            .map_err(|source| HttpError::Start {
                what: "thread",
                source,
            })?;
        tracing::info!(
            "web console listening on {}://{local} (reads {})",
            if secure { "https" } else { "http" },
            if settings.public_read {
                "open to all"
            } else {
                "need a login"
            }
        );
        Ok(Server {
            addr: local,
            stop,
            thread: Some(thread),
        })
    }

    /// The address it listens on.
    pub fn local_addr(&self) -> SocketAddr {
        self.addr
    }

    /// Stop accepting, let requests in progress finish (a short grace),
    /// and wait for the server's thread.
    pub fn stop(mut self) {
        self.stop_and_join();
    }

    fn stop_and_join(&mut self) {
        let _ = self.stop.send(true);
        if let Some(thread) = self.thread.take() {
            if thread.join().is_err() {
                tracing::error!("the web console's thread panicked");
            }
            tracing::info!("web console stopped");
        }
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        self.stop_and_join();
    }
}

/// What bounds a connection.
#[derive(Debug, Clone, Copy)]
struct Limits {
    header_bytes: usize,
    header_timeout: Duration,
    connections: usize,
}

impl Limits {
    fn of(settings: &Http) -> Self {
        Limits {
            header_bytes: settings.max_header_bytes.max(8192),
            header_timeout: Duration::from_secs_f64(settings.header_timeout_seconds),
            connections: settings.max_connections.max(1),
        }
    }
}

/// Wait until the stop is sent (or the sender is gone).
async fn until_stopped(stop: &mut watch::Receiver<bool>) {
    // The guard `wait_for` returns is dropped here: it must not be held
    // across an await of a spawned task.
    let _ = stop.wait_for(|s| *s).await.map(|_| ());
}

/// The TLS acceptor of `tls_cert` and `tls_key` (`None`: plain HTTP).
// rustls deprecates its ring provider for lacking post-quantum key
// exchange; aws-lc-rs, which has it, needs cmake and NASM to build. ring's
// TLS 1.2/1.3 suites are what a lab network's browsers negotiate today.
#[allow(deprecated)]
fn tls_acceptor(settings: &Http) -> Result<Option<TlsAcceptor>, HttpError> {
    use rustls::pki_types::pem::PemObject as _;
    use rustls::pki_types::{CertificateDer, PrivateKeyDer};
    let (Some(cert), Some(key)) = (&settings.tls_cert, &settings.tls_key) else {
        return Ok(None);
    };
    let bad = |path: &PathBuf, message: String| HttpError::Tls {
        path: path.clone(),
        message,
    };
    let chain = CertificateDer::pem_file_iter(cert)
        .and_then(|certs| certs.collect::<Result<Vec<_>, _>>())
        .map_err(|e| bad(cert, e.to_string()))?;
    if chain.is_empty() {
        return Err(bad(cert, "no certificate in the file".into()));
    }
    let key_der = PrivateKeyDer::from_pem_file(key).map_err(|e| bad(key, e.to_string()))?;
    let provider = Arc::new(rustls::crypto::ring::default_provider());
    let mut config = rustls::ServerConfig::builder_with_provider(provider)
        .with_safe_default_protocol_versions()
        .map_err(|e| bad(cert, e.to_string()))?
        .with_no_client_auth()
        .with_single_cert(chain, key_der)
        .map_err(|e| bad(key, e.to_string()))?;
    config.alpn_protocols = vec![b"http/1.1".to_vec()];
    Ok(Some(TlsAcceptor::from(Arc::new(config))))
}

/// Accept connections until `stopped`, each served on a task of its own
/// (after its TLS handshake, with `tls`); then wait (up to
/// [`STOP_GRACE`]) for those in progress.
async fn accept_loop(
    listener: tokio::net::TcpListener,
    app: Router,
    tls: Option<TlsAcceptor>,
    limits: Limits,
    mut stopped: watch::Receiver<bool>,
) {
    let slots = Arc::new(Semaphore::new(limits.connections));
    loop {
        // A free slot first: past the limit, clients wait in the kernel's
        // backlog rather than cost a task each.
        let slot = tokio::select! {
            _ = until_stopped(&mut stopped) => break,
            slot = Arc::clone(&slots).acquire_owned() => match slot {
                Ok(s) => s,
                Err(_) => break,
            },
        };
        let accepted = tokio::select! {
            _ = until_stopped(&mut stopped) => break,
            accepted = listener.accept() => accepted,
        };
        let (stream, peer) = match accepted {
            Ok(a) => a,
            Err(e) => {
                // Out of file descriptors and the like: wait, go on.
                tracing::warn!("http: cannot accept a connection: {e}");
                tokio::time::sleep(Duration::from_millis(100)).await;
                continue;
            }
        };
        let _ = stream.set_nodelay(true);
        let service = app
            .clone()
            .map_request(move |mut request: Request<Incoming>| {
                request.extensions_mut().insert(PeerAddr(peer));
                request
            });
        let stop = stopped.clone();
        let tls = tls.clone();
        tokio::spawn(async move {
            let _slot = slot;
            match tls {
                None => serve_connection(stream, service, limits, stop, peer).await,
                Some(acceptor) => {
                    // The handshake gets the time a request head gets.
                    let handshake =
                        tokio::time::timeout(limits.header_timeout, acceptor.accept(stream)).await;
                    match handshake {
                        Ok(Ok(stream)) => {
                            serve_connection(stream, service, limits, stop, peer).await
                        }
                        Ok(Err(e)) => tracing::debug!("http: TLS handshake with {peer}: {e}"),
                        Err(_) => tracing::debug!("http: TLS handshake with {peer} timed out"),
                    }
                }
            }
        });
    }
    // Every slot back: every connection is done (or the grace is over).
    let all = u32::try_from(limits.connections).unwrap_or(u32::MAX);
    let _ = tokio::time::timeout(STOP_GRACE, slots.acquire_many(all)).await;
}

/// Serve HTTP/1 on one connection until the client is done, or the stop
/// (then requests in progress get [`STOP_GRACE`]).
async fn serve_connection<IO, S>(
    io: IO,
    service: S,
    limits: Limits,
    mut stop: watch::Receiver<bool>,
    peer: SocketAddr,
) where
    IO: tokio::io::AsyncRead + tokio::io::AsyncWrite + Unpin + Send + 'static,
    S: tower::Service<Request<Incoming>, Response = axum::response::Response>
        + Clone
        + Send
        + 'static,
    S::Future: Send + 'static,
    S::Error: Into<Box<dyn std::error::Error + Send + Sync>>,
{
    let mut builder = hyper::server::conn::http1::Builder::new();
    builder
        .timer(TokioTimer::new())
        .header_read_timeout(limits.header_timeout)
        .max_buf_size(limits.header_bytes.max(8192))
        .max_header_size(limits.header_bytes);
    let connection = builder.serve_connection(TokioIo::new(io), TowerToHyperService::new(service));
    let mut connection = std::pin::pin!(connection);
    tokio::select! {
        served = connection.as_mut() => {
            if let Err(e) = served {
                tracing::debug!("http: connection from {peer}: {e}");
            }
        }
        _ = until_stopped(&mut stop) => {
            connection.as_mut().graceful_shutdown();
            let _ = tokio::time::timeout(STOP_GRACE, connection).await;
        }
    }
}

/// The routes, and the limits and headers every response gets.
fn router(state: Arc<AppState>) -> Router {
    let settings = state.settings.clone();
    let timeout = Duration::from_secs_f64(settings.request_timeout_seconds);
    Router::new()
        .route("/", get(pages::overview))
        .route("/scans/{id}", get(pages::scan_page))
        .route("/scans/{id}/review", post(pages::review_form))
        .route("/library", get(pages::library))
        .route("/status", get(pages::status))
        .route("/login", get(pages::login_form).post(pages::login))
        .route("/logout", post(pages::logout))
        .route("/healthz", get(api::healthz))
        .route("/metrics", get(metrics::metrics))
        .route("/api/v1/openapi.json", get(openapi::openapi))
        .route("/api/v1/scans", get(api::list_scans))
        .route("/api/v1/scans/{id}", get(api::get_scan))
        .route("/api/v1/scans/{id}/review", post(api::review))
        .route(
            "/api/v1/scans/{id}/add-to-library",
            post(api::add_to_library),
        )
        .route("/api/v1/references", get(api::references))
        .route("/api/v1/status", get(api::status))
        .route("/api/v1/changes", get(api::changes))
        .route("/api/v1/session", get(pages::session))
        .fallback(api::not_found)
        .with_state(state)
        .layer(DefaultBodyLimit::max(settings.max_body_bytes))
        .layer(RequestBodyLimitLayer::new(settings.max_body_bytes))
        .layer(TimeoutLayer::with_status_code(
            StatusCode::REQUEST_TIMEOUT,
            timeout,
        ))
        .layer(SetResponseHeaderLayer::if_not_present(
            header::X_CONTENT_TYPE_OPTIONS,
            HeaderValue::from_static("nosniff"),
        ))
        .layer(SetResponseHeaderLayer::if_not_present(
            header::X_FRAME_OPTIONS,
            HeaderValue::from_static("DENY"),
        ))
        .layer(SetResponseHeaderLayer::if_not_present(
            header::REFERRER_POLICY,
            HeaderValue::from_static("no-referrer"),
        ))
}

#[cfg(test)]
mod tests {
    use super::requires_curators;

    #[test]
    fn only_loopback_serves_without_curators() {
        for (addr, needs) in [
            ("127.0.0.1:8472", false),
            ("127.0.0.2:1", false),
            ("[::1]:8472", false),
            ("0.0.0.0:8472", true),
            ("[::]:8472", true),
            ("192.0.2.7:80", true),
            ("[::ffff:127.0.0.1]:80", true),
        ] {
            let addr = addr.parse().unwrap();
            assert_eq!(requires_curators(&addr), needs, "{addr}");
        }
    }
}

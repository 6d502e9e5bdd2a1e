//! The browser front-end: an HTTP server (axum) with the page at `/`, the stream at `/ws`
//! (a WebSocket: JPEG pictures and JSON status out, JSON commands in, see [`protocol`]) and
//! the latest status at `/status`.
//!
//! * One client controls the session; the others watch (their commands are answered with a
//!   polite refusal) until the controller leaves, when the next one to send a command takes
//!   over.
//! * The stream never holds the simulation up: frames reach the server through a slot that
//!   keeps only the latest, and each client gets the latest when it is ready for one (a slow
//!   client sees fewer frames; one that stops reading is dropped after [`SEND_TIMEOUT`]); the
//!   kernel queues at most [`UNSENT_BYTES`] unsent for a client, so what it gets is recent.
//!   Memory stays bounded: one encoded frame, one in flight per client, [`MAX_CLIENTS`].
//! * Client messages are at most [`protocol::MAX_MESSAGE_BYTES`]; a larger one closes the
//!   connection (WebSocket code 1009), garbage is answered with an error message, and a
//!   client that sends [`MAX_BAD_MESSAGES`] of those is closed (code 1008).

pub mod encoder;
pub mod protocol;

use crate::session::{Commands, SceneInfo, Session};
use axum::Router;
use axum::body::Bytes;
use axum::extract::State;
use axum::extract::ws::{CloseFrame, Message, Utf8Bytes, WebSocket, WebSocketUpgrade, close_code};
use axum::http::StatusCode;
use axum::response::{Html, IntoResponse, Response};
use axum::routing::get;
use axum::serve::ListenerExt;
use encoder::Encoded;
use futures_util::{SinkExt, StreamExt};
use std::net::{IpAddr, Ipv4Addr, SocketAddr, TcpListener};
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;
use tokio::sync::{mpsc, watch};

/// The page.
const PAGE: &str = include_str!("page.html");
/// Clients connected at most; more are answered 503.
pub const MAX_CLIENTS: usize = 16;
/// A client that has not taken a message for this long is dropped.
pub const SEND_TIMEOUT: Duration = Duration::from_secs(10);
/// Bad messages a client may send before it is closed.
pub const MAX_BAD_MESSAGES: u32 = 64;
/// The default address of `--serve`.
pub const DEFAULT_ADDR: &str = "127.0.0.1:8080";

/// How the server streams.
#[derive(Clone, Debug)]
pub struct ServeOptions {
    /// JPEG quality (1 to 100).
    pub quality: u8,
    /// Largest picture a client may ask for.
    pub max_size: (u32, u32),
}

impl Default for ServeOptions {
    fn default() -> Self {
        ServeOptions {
            quality: crate::jpeg::DEFAULT_QUALITY,
            max_size: (1920, 1080),
        }
    }
}

/// The address `HOST:PORT` (HOST an IP address or `localhost`; a bare `PORT` means
/// 127.0.0.1), with a message that says how to write one.
pub fn parse_addr(s: &str) -> Result<SocketAddr, String> {
    let bad = || {
        format!(
            "bad address `{s}` for --serve: give HOST:PORT such as {DEFAULT_ADDR} (HOST an IP \
             address of this machine or localhost; 0.0.0.0 serves every network, which lets \
             anyone who reaches this machine steer the run)"
        )
    };
    let s = s.trim();
    if let Ok(port) = s.parse::<u16>() {
        return Ok(SocketAddr::new(IpAddr::V4(Ipv4Addr::LOCALHOST), port));
    }
    if let Some(port) = s.strip_prefix("localhost:") {
        let port = port.parse::<u16>().map_err(|_| bad())?;
        return Ok(SocketAddr::new(IpAddr::V4(Ipv4Addr::LOCALHOST), port));
    }
    s.parse::<SocketAddr>().map_err(|_| bad())
}

/// Bind the server's socket, with messages that say what to do when it cannot be.
pub fn bind(addr: SocketAddr) -> Result<TcpListener, String> {
    TcpListener::bind(addr).map_err(|e| {
        use std::io::ErrorKind as K;
        match e.kind() {
            K::AddrInUse => format!(
                "port {} on {} is in use (another rtmpm view, or another server): choose \
                 another port, e.g. --serve {}:{}",
                addr.port(),
                addr.ip(),
                addr.ip(),
                addr.port().wrapping_add(1).max(1024)
            ),
            K::AddrNotAvailable => format!(
                "cannot serve on {addr}: {} is not an address of this machine (use \
                 127.0.0.1, and an SSH tunnel to watch from elsewhere)",
                addr.ip()
            ),
            K::PermissionDenied => format!(
                "not allowed to serve on {addr} ({e}): ports below 1024 need privileges; use \
                 a port such as 8080"
            ),
            _ => format!("cannot serve on {addr}: {e}"),
        }
    })
}

/// Who controls the session.
#[derive(Default)]
struct Seat(Mutex<Option<u64>>);

impl Seat {
    /// True when client `id` holds the seat, taking it if free.
    fn claim(&self, id: u64) -> bool {
        let mut s = self.0.lock().unwrap_or_else(|e| e.into_inner());
        match *s {
            Some(holder) => holder == id,
            None => {
                *s = Some(id);
                true
            }
        }
    }

    fn release(&self, id: u64) {
        let mut s = self.0.lock().unwrap_or_else(|e| e.into_inner());
        if *s == Some(id) {
            *s = None;
        }
    }
}

struct Shared {
    commands: Commands,
    frames: watch::Receiver<Option<Arc<Encoded>>>,
    seat: Seat,
    next_id: AtomicU64,
    clients: AtomicUsize,
    info: SceneInfo,
    max_size: (u32, u32),
    /// The latest frame's status, for `/status`.
    slot: Arc<crate::frame::FrameSlot>,
}

/// Serve `session` on `listener` until `shutdown` completes or the session ends; the
/// caller then finishes the session.
pub fn serve(
    listener: TcpListener,
    session: &Session,
    options: &ServeOptions,
    shutdown: impl Future<Output = ()> + Send + 'static,
) -> Result<(), String> {
    let (tx, rx) = watch::channel(None);
    let encoder = encoder::start(session.frames(), tx, options.quality)
        .map_err(|e| format!("cannot start the stream encoder: {e}"))?;
    let shared = Arc::new(Shared {
        commands: session.commands(),
        frames: rx,
        seat: Seat::default(),
        next_id: AtomicU64::new(1),
        clients: AtomicUsize::new(0),
        info: session.info.clone(),
        max_size: options.max_size,
        slot: session.frames(),
    });
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .map_err(|e| format!("cannot start the server's runtime: {e}"))?;
    let result = runtime.block_on(run(listener, shared, shutdown));
    drop(runtime);
    // The encoder ends with the session (the caller finishes it).
    drop(encoder);
    result
}

async fn run(
    listener: TcpListener,
    shared: Arc<Shared>,
    shutdown: impl Future<Output = ()> + Send + 'static,
) -> Result<(), String> {
    listener
        .set_nonblocking(true)
        .map_err(|e| format!("cannot serve: {e}"))?;
    let listener = tokio::net::TcpListener::from_std(listener)
        .map_err(|e| format!("cannot serve: {e}"))?
        .tap_io(short_queue);
    let mut ended = shared.frames.clone();
    let app = Router::new()
        .route("/", get(page))
        .route("/ws", get(stream))
        .route("/status", get(status))
        .fallback(not_found)
        .with_state(shared);
    let stop = async move {
        tokio::select! {
            _ = shutdown => {}
            // The encoder drops its sender when the session has ended.
            _ = async { while ended.changed().await.is_ok() {} } => {}
        }
    };
    axum::serve(listener, app)
        .with_graceful_shutdown(stop)
        .await
        .map_err(|e| format!("the server failed: {e}"))
}

/// Unsent bytes the kernel may queue for a client before a send waits (Linux).
pub const UNSENT_BYTES: u32 = 32 * 1024;

/// Keep the kernel's queue of a connection short: without it a slow client's socket buffer
/// (tuned up to megabytes) would fill with old pictures, each reaching it ever later, and a send
/// would wait for megabytes to drain. With at most [`UNSENT_BYTES`] unsent, the next send waits
/// for the client, and the picture sent then is the latest.
fn short_queue(tcp: &mut tokio::net::TcpStream) {
    let _ = tcp.set_nodelay(true);
    let sock = socket2::SockRef::from(&*tcp);
    #[cfg(any(target_os = "linux", target_os = "android"))]
    let _ = sock.set_tcp_notsent_lowat(UNSENT_BYTES);
    #[cfg(not(any(target_os = "linux", target_os = "android")))]
    let _ = sock.set_send_buffer_size(4 * UNSENT_BYTES as usize);
}

async fn page() -> Html<&'static str> {
    Html(PAGE)
}

async fn not_found() -> (StatusCode, &'static str) {
    (
        StatusCode::NOT_FOUND,
        "not found: the viewer is at /, its stream at /ws, its status at /status\n",
    )
}

async fn status(State(shared): State<Arc<Shared>>) -> Response {
    match shared.slot.latest() {
        Some(f) => (
            [(axum::http::header::CONTENT_TYPE, "application/json")],
            encoder::status_message(&f, 0, 0.0),
        )
            .into_response(),
        None => (StatusCode::SERVICE_UNAVAILABLE, "no frame yet\n").into_response(),
    }
}

async fn stream(ws: WebSocketUpgrade, State(shared): State<Arc<Shared>>) -> Response {
    if shared.clients.load(Ordering::SeqCst) >= MAX_CLIENTS {
        return (
            StatusCode::SERVICE_UNAVAILABLE,
            format!("{MAX_CLIENTS} clients are watching already: close one and try again\n"),
        )
            .into_response();
    }
    let limit = protocol::MAX_MESSAGE_BYTES;
    ws.max_message_size(limit)
        .max_frame_size(limit)
        .on_upgrade(move |socket| client(socket, shared))
}

fn json(v: serde_json::Value) -> Message {
    Message::Text(Utf8Bytes::from(v.to_string()))
}

fn role_message(controller: bool) -> Message {
    json(serde_json::json!({
        "type": "role",
        "role": if controller { "controller" } else { "viewer" },
    }))
}

fn error_message(text: &str) -> Message {
    json(serde_json::json!({ "type": "error", "message": text }))
}

fn close(code: u16, reason: &str) -> Message {
    Message::Close(Some(CloseFrame {
        code,
        reason: Utf8Bytes::from(reason.to_string()),
    }))
}

/// One client: its writer sends the latest frames and the replies, its reader takes the
/// commands.
async fn client(socket: WebSocket, shared: Arc<Shared>) {
    let id = shared.next_id.fetch_add(1, Ordering::SeqCst);
    shared.clients.fetch_add(1, Ordering::SeqCst);
    let controller = shared.seat.claim(id);
    let (sink, stream) = socket.split();
    let (reply_tx, reply_rx) = mpsc::channel::<Message>(16);
    let hello = json(serde_json::json!({
        "type": "hello",
        "scene": shared.info,
        "color_modes": rtmpm_scene::ColorBy::ALL.map(|c| c.name()),
        "max_message_bytes": protocol::MAX_MESSAGE_BYTES,
    }));
    let _ = reply_tx.try_send(hello);
    let _ = reply_tx.try_send(role_message(controller));
    let writer = write(sink, shared.frames.clone(), reply_rx);
    let reader = read(stream, &shared, id, reply_tx);
    tokio::pin!(writer, reader);
    tokio::select! {
        _ = &mut writer => {}
        _ = &mut reader => {
            // Let the writer send what the reader left (a close frame) before going.
            let _ = tokio::time::timeout(Duration::from_secs(1), writer).await;
        }
    }
    shared.seat.release(id);
    shared.clients.fetch_sub(1, Ordering::SeqCst);
}

/// Send with the timeout; false when the client is gone or too slow.
async fn send(sink: &mut futures_util::stream::SplitSink<WebSocket, Message>, m: Message) -> bool {
    matches!(
        tokio::time::timeout(SEND_TIMEOUT, sink.send(m)).await,
        Ok(Ok(()))
    )
}

async fn write(
    mut sink: futures_util::stream::SplitSink<WebSocket, Message>,
    mut frames: watch::Receiver<Option<Arc<Encoded>>>,
    mut replies: mpsc::Receiver<Message>,
) {
    frames.mark_changed();
    loop {
        tokio::select! {
            // Replies first: the hello and role precede the first picture.
            biased;
            r = replies.recv() => match r {
                Some(m) => {
                    let closing = matches!(m, Message::Close(_));
                    if !send(&mut sink, m).await || closing {
                        return;
                    }
                }
                None => return,
            },
            r = frames.changed() => {
                if r.is_err() {
                    let _ = send(&mut sink, close(close_code::AWAY, "the session has ended")).await;
                    return;
                }
                let f = frames.borrow_and_update().clone();
                if let Some(f) = f {
                    let status = Message::Text(Utf8Bytes::from(f.status.clone()));
                    if !send(&mut sink, status).await
                        || !send(&mut sink, Message::Binary(Bytes::clone(&f.jpeg))).await
                    {
                        return;
                    }
                }
            }
        }
    }
}

async fn read(
    mut stream: futures_util::stream::SplitStream<WebSocket>,
    shared: &Shared,
    id: u64,
    replies: mpsc::Sender<Message>,
) {
    let mut bad = 0u32;
    let mut was_controller = shared.seat.claim(id);
    while let Some(m) = stream.next().await {
        let text = match m {
            Ok(Message::Text(t)) => t,
            Ok(Message::Close(_)) => return,
            Ok(Message::Ping(_) | Message::Pong(_)) => continue,
            Ok(Message::Binary(_)) => {
                bad += 1;
                let _ = replies.try_send(error_message(
                    "binary messages are not commands: send JSON text such as {\"cmd\": \"pause\"}",
                ));
                if bad >= MAX_BAD_MESSAGES {
                    let _ = replies.try_send(close(close_code::POLICY, "too many bad messages"));
                    return;
                }
                continue;
            }
            Err(e) => {
                let reason = e.to_string();
                let code = if reason.contains("too long") || reason.contains("size") {
                    close_code::SIZE
                } else {
                    close_code::PROTOCOL
                };
                let _ = replies.try_send(close(code, &format!("closing: {reason}")));
                return;
            }
        };
        let command = protocol::parse(&text, &shared.info.materials, shared.max_size);
        let answer = match command {
            Err(e) => {
                bad += 1;
                Some(error_message(&e))
            }
            Ok(c) => {
                let controller = shared.seat.claim(id);
                if controller != was_controller {
                    was_controller = controller;
                    let _ = replies.try_send(role_message(controller));
                }
                if !controller {
                    Some(error_message(
                        "another client controls this session: you can watch; you get the \
                         controls when it leaves",
                    ))
                } else {
                    shared
                        .commands
                        .send(c)
                        .err()
                        .map(|e| error_message(&e.to_string()))
                }
            }
        };
        if let Some(a) = answer {
            let _ = replies.try_send(a);
        }
        if bad >= MAX_BAD_MESSAGES {
            let _ = replies.try_send(close(close_code::POLICY, "too many bad messages"));
            return;
        }
    }
}

/// Completes on Ctrl-C (SIGINT) or SIGTERM: the end of a served session (poll it inside a
/// runtime, as [`serve`] does).
pub async fn interrupted() {
    #[cfg(unix)]
    let term = async {
        match tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()) {
            Ok(mut s) => {
                s.recv().await;
            }
            Err(_) => std::future::pending::<()>().await,
        }
    };
    #[cfg(not(unix))]
    let term = std::future::pending::<()>();
    tokio::select! {
        _ = tokio::signal::ctrl_c() => {}
        _ = term => {}
    }
}

/// Wait until the session ends by itself (its frame limit) or the process is interrupted
/// ([`interrupted`]), looking every `poll`.
pub fn until_ended_or_interrupted(session: &Session, poll: Duration) -> Result<(), String> {
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .map_err(|e| format!("cannot start a runtime: {e}"))?;
    runtime.block_on(async {
        tokio::select! {
            _ = interrupted() => {}
            _ = async {
                while !session.ended() {
                    tokio::time::sleep(poll).await;
                }
            } => {}
        }
    });
    Ok(())
}

#[cfg(test)]
mod tests;

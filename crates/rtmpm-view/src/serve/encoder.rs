//! The bridge from a session's frames to the stream: a thread that takes the newest frame,
//! encodes it as JPEG once for every client, and puts it in a `tokio::sync::watch` (which,
//! like the session's slot, holds only the latest). Nothing is encoded while no client
//! watches; the frame waiting then is encoded when one comes.

use crate::frame::{Ended, Frame, FrameSlot};
use crate::jpeg::encode_jpeg;
use axum::body::Bytes;
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};
use tokio::sync::watch;

/// How often the encoder looks for a new client while a frame waits (ms).
const POLL: Duration = Duration::from_millis(50);

/// A frame as the stream sends it.
#[derive(Debug)]
pub struct Encoded {
    /// The frame's [`crate::Status::seq`].
    pub seq: u64,
    /// The status message (JSON text) sent before the picture.
    pub status: String,
    /// The picture (JPEG).
    pub jpeg: Bytes,
}

/// The status message of a frame: the [`crate::Status`] fields, `"type": "status"`, and the
/// encoder's own figures (`jpeg_bytes`, `encode_ms`).
pub fn status_message(f: &Frame, jpeg_bytes: usize, encode_ms: f64) -> String {
    let mut v = serde_json::to_value(&f.status).unwrap_or_default();
    if let Some(o) = v.as_object_mut() {
        o.insert("type".into(), "status".into());
        o.insert("jpeg_bytes".into(), jpeg_bytes.into());
        o.insert("encode_ms".into(), encode_ms.into());
    }
    v.to_string()
}

/// Start the encoder thread: frames of `slot` into `tx` at JPEG `quality`. It ends when the
/// session has ended (dropping `tx`, which tells the clients) or every receiver is gone.
pub fn start(
    slot: Arc<FrameSlot>,
    tx: watch::Sender<Option<Arc<Encoded>>>,
    quality: u8,
) -> std::io::Result<JoinHandle<()>> {
    std::thread::Builder::new()
        .name("stream encoder".into())
        .spawn(move || run(&slot, &tx, quality))
}

fn run(slot: &FrameSlot, tx: &watch::Sender<Option<Arc<Encoded>>>, quality: u8) {
    let mut seen = 0;
    let mut waiting: Option<Arc<Frame>> = None;
    loop {
        match slot.wait_newer(seen, POLL) {
            Err(Ended) => break,
            Ok(Some(f)) => {
                seen = f.status.seq;
                waiting = Some(f);
            }
            Ok(None) if tx.is_closed() => break,
            Ok(None) => {}
        }
        // The server holds one receiver; more are clients.
        if tx.receiver_count() > 1
            && let Some(f) = waiting.take()
        {
            let t0 = Instant::now();
            match encode_jpeg(&f.image, quality) {
                Ok(jpeg) => {
                    let ms = t0.elapsed().as_secs_f64() * 1e3;
                    tx.send_replace(Some(Arc::new(Encoded {
                        seq: f.status.seq,
                        status: status_message(&f, jpeg.len(), ms),
                        jpeg: Bytes::from(jpeg),
                    })));
                }
                Err(e) => eprintln!("view: frame {} not streamed: {e}", f.status.seq),
            }
        }
    }
}

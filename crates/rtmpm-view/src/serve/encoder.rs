//! The bridge from a session's frames to the stream: threads that take the newest frame,
//! encode it as JPEG once for every client (each frame by one of them) and put it in a
//! `tokio::sync::watch` (which, like the session's slot, holds only the latest). Nothing is encoded while no client
//! watches; the frame waiting then is encoded when one comes.

use crate::frame::{Ended, Frame, FrameSlot};
use crate::jpeg::encode_jpeg;
use axum::body::Bytes;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
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

/// Encoder threads: one JPEG of a 1280x720 picture takes about 10 ms of a core, so one thread
/// streams at most about 100 pictures/s (the snow 1.33M on an H200 simulates 124 frames/s);
/// two where the machine has the cores for them (a quarter of its cores, so a small machine's
/// simulation keeps its threads).
pub fn encoder_threads() -> usize {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    (cores / 4).clamp(1, 2)
}

/// Start the encoder threads ([`encoder_threads`]): frames of `slot` into `tx` at JPEG
/// `quality`, each frame encoded by one of them, the newest one published. They end when the
/// session has ended (dropping `tx`, which tells the clients) or every receiver is gone.
pub fn start(
    slot: Arc<FrameSlot>,
    tx: watch::Sender<Option<Arc<Encoded>>>,
    quality: u8,
) -> std::io::Result<Vec<JoinHandle<()>>> {
    let tx = Arc::new(tx);
    let claimed = Arc::new(AtomicU64::new(0));
    (0..encoder_threads())
        .map(|i| {
            let (slot, tx, claimed) = (slot.clone(), tx.clone(), claimed.clone());
            std::thread::Builder::new()
                .name(format!("stream encoder {i}"))
                .spawn(move || run(&slot, &tx, &claimed, quality))
        })
        .collect()
}

/// One encoder thread: waits for a frame newer than any taken, takes it (`claimed`: no two
/// threads encode the same frame), encodes it once a client watches, and publishes it unless a
/// newer one has been published meanwhile.
fn run(
    slot: &FrameSlot,
    tx: &watch::Sender<Option<Arc<Encoded>>>,
    claimed: &AtomicU64,
    quality: u8,
) {
    let mut seen = 0;
    let mut waiting: Option<Arc<Frame>> = None;
    loop {
        match slot.wait_newer(seen.max(claimed.load(Ordering::Acquire)), POLL) {
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
            && claimed.fetch_max(f.status.seq, Ordering::AcqRel) < f.status.seq
        {
            let t0 = Instant::now();
            match encode_jpeg(&f.image, quality) {
                Ok(jpeg) => {
                    let ms = t0.elapsed().as_secs_f64() * 1e3;
                    let e = Arc::new(Encoded {
                        seq: f.status.seq,
                        status: status_message(&f, jpeg.len(), ms),
                        jpeg: Bytes::from(jpeg),
                    });
                    tx.send_if_modified(|cur| {
                        let newer = cur.as_ref().is_none_or(|c| c.seq < e.seq);
                        if newer {
                            *cur = Some(e);
                        }
                        newer
                    });
                }
                Err(e) => eprintln!("view: frame {} not streamed: {e}", f.status.seq),
            }
        }
    }
}

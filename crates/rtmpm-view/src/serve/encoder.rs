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
    start_threads(slot, tx, quality, encoder_threads())
}

/// [`start`] with `threads` encoder threads.
fn start_threads(
    slot: Arc<FrameSlot>,
    tx: watch::Sender<Option<Arc<Encoded>>>,
    quality: u8,
    threads: usize,
) -> std::io::Result<Vec<JoinHandle<()>>> {
    let tx = Arc::new(tx);
    let claimed = Arc::new(AtomicU64::new(0));
    (0..threads.max(1))
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
                    publish_newer(
                        tx,
                        Encoded {
                            seq: f.status.seq,
                            status: status_message(&f, jpeg.len(), ms),
                            jpeg: Bytes::from(jpeg),
                        },
                    );
                }
                Err(e) => eprintln!("view: frame {} not streamed: {e}", f.status.seq),
            }
        }
    }
}

/// Publish `e` unless a newer frame has been published (another encoder finished a later frame
/// first); true when published.
fn publish_newer(tx: &watch::Sender<Option<Arc<Encoded>>>, e: Encoded) -> bool {
    tx.send_if_modified(|cur| {
        let newer = cur.as_ref().is_none_or(|c| c.seq < e.seq);
        if newer {
            *cur = Some(Arc::new(e));
        }
        newer
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Status;
    use rtmpm_render::Image;

    #[test]
    fn an_older_frame_finished_late_is_not_published_over_a_newer_one() {
        let (tx, rx) = watch::channel(None);
        let e = |seq| Encoded {
            seq,
            status: String::new(),
            jpeg: Bytes::new(),
        };
        assert!(publish_newer(&tx, e(5)));
        assert!(!publish_newer(&tx, e(3)));
        assert!(!publish_newer(&tx, e(5)));
        assert_eq!(rx.borrow().as_ref().map(|c| c.seq), Some(5));
        assert!(publish_newer(&tx, e(6)));
        assert_eq!(rx.borrow().as_ref().map(|c| c.seq), Some(6));
    }

    /// Two encoders on frames published faster than one encodes them: every frame is encoded
    /// at most once, the published sequence only goes forward, and the last frame is published.
    #[test]
    fn two_encoders_publish_frames_in_order_and_the_last_one() {
        let slot = Arc::new(FrameSlot::default());
        // The server's receiver and a client's: the encoders encode only while a client watches.
        let (tx, server) = watch::channel(None);
        let mut rx = server.clone();
        let threads = start_threads(slot.clone(), tx, 80, 2).expect("encoders");
        let last = 60u64;
        let publisher = {
            let slot = slot.clone();
            std::thread::spawn(move || {
                for seq in 1..=last {
                    let status = Status {
                        seq,
                        ..Status::default()
                    };
                    let image = Image::new(320, 180, [(seq % 256) as u8, 40, 90]);
                    slot.publish(Arc::new(Frame { image, status }));
                    std::thread::sleep(Duration::from_millis(1));
                }
            })
        };
        let mut seen = Vec::new();
        let t0 = Instant::now();
        while seen.last() != Some(&last) && t0.elapsed() < Duration::from_secs(20) {
            if rx.has_changed().unwrap_or(false) {
                if let Some(e) = rx.borrow_and_update().as_ref() {
                    assert!(!e.jpeg.is_empty());
                    seen.push(e.seq);
                }
            } else {
                std::thread::sleep(Duration::from_millis(1));
            }
        }
        publisher.join().expect("publisher");
        slot.close();
        drop((rx, server));
        for t in threads {
            t.join().expect("encoder");
        }
        assert_eq!(
            seen.last(),
            Some(&last),
            "the last frame was published: {seen:?}"
        );
        assert!(
            seen.windows(2).all(|w| w[0] < w[1]),
            "out of order: {seen:?}"
        );
    }
}

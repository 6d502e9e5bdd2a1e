//! The server over real sockets: the page, the stream, one controller, bad input, a client
//! that stops reading.

use super::*;
use crate::session::{SessionOptions, SimFactory};
use futures_util::{SinkExt, StreamExt};
use rtmpm_cpu::CpuBackend;
use rtmpm_driver::Simulation;
use rtmpm_scene::Scene;
use std::io::{Read, Write};
use std::time::Instant;
use tokio_tungstenite::tungstenite::Message as Ws;

const SCENE: &str = "[domain]\nmin = [0,0,0]\nmax = [1,1,1]\ndx = 0.05\n\
    [time]\nduration = 100.0\nfps = 50\ndt = 1e-3\n\
    [[material]]\nname = \"water\"\ntype = \"fluid\"\ndensity = 1000.0\nbulk_modulus = 1e4\n\
    [[body]]\nmaterial = \"water\"\nshape = \"box\"\nmin = [0.3,0.15,0.3]\nmax = [0.7,0.5,0.7]\n";

fn factory() -> SimFactory {
    Box::new(|| {
        let scene = Scene::from_toml(SCENE, "<test>").map_err(|e| e.to_string())?;
        let p = scene.sample_particles().map_err(|e| e.to_string())?;
        let b = CpuBackend::new(&scene, p, Some(1)).map_err(|e| e.to_string())?;
        Ok(Simulation::new(scene, Box::new(b)))
    })
}

/// Serve a small session on an ephemeral port of 127.0.0.1, run `test` against its address
/// on a runtime of its own, then stop the server.
fn with_server(paused: bool, test: impl AsyncFnOnce(SocketAddr)) {
    let opts = SessionOptions {
        width: 96,
        height: 64,
        paused,
        shadows: false,
        ..Default::default()
    };
    let session = Session::start(factory(), opts, None).expect("session");
    let listener = bind(parse_addr("127.0.0.1:0").unwrap()).expect("bind");
    let addr = listener.local_addr().unwrap();
    let (stop_tx, stop_rx) = tokio::sync::oneshot::channel::<()>();
    std::thread::scope(|s| {
        let server = s.spawn(|| {
            serve(listener, &session, &ServeOptions::default(), async {
                let _ = stop_rx.await;
            })
        });
        let rt = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .unwrap();
        rt.block_on(test(addr));
        let _ = stop_tx.send(());
        server.join().unwrap().expect("server");
    });
    session.finish().unwrap();
}

type Client =
    tokio_tungstenite::WebSocketStream<tokio_tungstenite::MaybeTlsStream<tokio::net::TcpStream>>;

async fn connect(addr: SocketAddr) -> Client {
    tokio_tungstenite::connect_async(format!("ws://{addr}/ws"))
        .await
        .expect("connect")
        .0
}

/// The next JSON message of `kind` (skipping others and pictures), within 20 s.
async fn next_json(c: &mut Client, kind: &str) -> serde_json::Value {
    let deadline = Instant::now() + Duration::from_secs(20);
    loop {
        let left = deadline.saturating_duration_since(Instant::now());
        let m = tokio::time::timeout(left, c.next())
            .await
            .unwrap_or_else(|_| panic!("no `{kind}` message within 20 s"))
            .expect("open")
            .expect("message");
        if let Ws::Text(t) = m {
            let v: serde_json::Value = serde_json::from_str(&t).unwrap();
            if v["type"] == kind {
                return v;
            }
        }
    }
}

/// The next status with `pred`, within 20 s.
async fn status_where(
    c: &mut Client,
    pred: impl Fn(&serde_json::Value) -> bool,
) -> serde_json::Value {
    loop {
        let s = next_json(c, "status").await;
        if pred(&s) {
            return s;
        }
    }
}

async fn cmd(c: &mut Client, text: &str) {
    c.send(Ws::Text(text.into())).await.expect("send");
}

fn http_get(addr: SocketAddr, path: &str) -> String {
    let mut s = std::net::TcpStream::connect(addr).unwrap();
    write!(
        s,
        "GET {path} HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n"
    )
    .unwrap();
    let mut out = String::new();
    s.read_to_string(&mut out).unwrap();
    out
}

#[test]
fn the_page_the_status_and_unknown_paths() {
    with_server(true, async |addr| {
        let page = tokio::task::spawn_blocking(move || http_get(addr, "/"))
            .await
            .unwrap();
        assert!(
            page.starts_with("HTTP/1.1 200") && page.contains("rtmpm view"),
            "{page}"
        );
        let st = tokio::task::spawn_blocking(move || http_get(addr, "/status"))
            .await
            .unwrap();
        assert!(
            st.contains("\"type\":\"status\"") && st.contains("\"paused\":true"),
            "{st}"
        );
        let nf = tokio::task::spawn_blocking(move || http_get(addr, "/nope"))
            .await
            .unwrap();
        assert!(nf.starts_with("HTTP/1.1 404"), "{nf}");
    });
}

#[test]
fn frames_stream_and_the_controller_steers_while_a_second_client_watches() {
    with_server(false, async |addr| {
        let mut a = connect(addr).await;
        let hello = next_json(&mut a, "hello").await;
        assert_eq!(hello["scene"]["materials"][0], "water");
        assert_eq!(next_json(&mut a, "role").await["role"], "controller");
        // Pictures follow their status, and the time goes on.
        let s1 = next_json(&mut a, "status").await;
        let pic = loop {
            match a.next().await.unwrap().unwrap() {
                Ws::Binary(b) => break b,
                _ => continue,
            }
        };
        assert_eq!(&pic[..2], &[0xFF, 0xD8], "a JPEG");
        let t1 = s1["time"].as_f64().unwrap();
        status_where(&mut a, |s| s["time"].as_f64().unwrap() > t1 + 0.05).await;
        // A second client watches; its commands are refused politely.
        let mut b = connect(addr).await;
        assert_eq!(next_json(&mut b, "role").await["role"], "viewer");
        next_json(&mut b, "status").await;
        cmd(&mut b, r#"{"cmd":"pause"}"#).await;
        let e = next_json(&mut b, "error").await;
        assert!(
            e["message"]
                .as_str()
                .unwrap()
                .contains("another client controls"),
            "{e}"
        );
        // The controller pauses: the time stops.
        cmd(&mut a, r#"{"cmd":"pause"}"#).await;
        let p = status_where(&mut a, |s| s["paused"] == true).await;
        cmd(&mut a, r#"{"cmd":"step"}"#).await;
        let st = status_where(&mut a, |s| s["step"].as_u64() > p["step"].as_u64()).await;
        assert_eq!(
            st["step"].as_u64().unwrap(),
            p["step"].as_u64().unwrap() + 1
        );
        cmd(&mut a, r#"{"cmd":"reset"}"#).await;
        status_where(&mut a, |s| s["step"] == 0 && s["time"] == 0.0).await;
        // The controller leaves: the watcher's next command takes over.
        a.close(None).await.unwrap();
        drop(a);
        tokio::time::sleep(Duration::from_millis(200)).await;
        cmd(&mut b, r#"{"cmd":"resume"}"#).await;
        assert_eq!(next_json(&mut b, "role").await["role"], "controller");
        status_where(&mut b, |s| s["paused"] == false).await;
    });
}

#[test]
fn garbage_is_answered_and_huge_messages_close_the_connection() {
    with_server(true, async |addr| {
        let mut c = connect(addr).await;
        next_json(&mut c, "status").await;
        cmd(&mut c, "not json at all").await;
        let e = next_json(&mut c, "error").await;
        assert!(
            e["message"].as_str().unwrap().contains("cannot read"),
            "{e}"
        );
        c.send(Ws::Binary(vec![1, 2, 3].into())).await.unwrap();
        let e = next_json(&mut c, "error").await;
        assert!(e["message"].as_str().unwrap().contains("binary"), "{e}");
        // Still served: a command works.
        cmd(&mut c, r#"{"cmd":"step"}"#).await;
        status_where(&mut c, |s| s["step"] == 1).await;
        // Over the limit: closed with 1009 (message too big).
        let huge = format!(
            r#"{{"cmd":"pause","pad":"{}"}}"#,
            "x".repeat(protocol::MAX_MESSAGE_BYTES)
        );
        let _ = c.send(Ws::Text(huge.into())).await;
        let code = loop {
            match tokio::time::timeout(Duration::from_secs(10), c.next()).await {
                Ok(Some(Ok(Ws::Close(Some(f))))) => break Some(u16::from(f.code)),
                Ok(Some(Ok(_))) => continue,
                _ => break None,
            }
        };
        assert_eq!(code, Some(close_code::SIZE));
        // Others can still connect.
        let mut d = connect(addr).await;
        next_json(&mut d, "status").await;
    });
}

#[test]
fn a_client_that_stops_reading_holds_nothing_up() {
    with_server(false, async |addr| {
        // A client that never reads.
        let stalled = connect(addr).await;
        let mut a = connect(addr).await;
        let s0 = next_json(&mut a, "status").await;
        let t0 = Instant::now();
        // The simulation and the other client go on for two seconds.
        let s1 = status_where(&mut a, |_| t0.elapsed() > Duration::from_secs(2)).await;
        let steps = s1["step"].as_u64().unwrap() - s0["step"].as_u64().unwrap();
        assert!(steps > 50, "{steps} steps in 2 s");
        assert!(s1["seq"].as_u64().unwrap() > s0["seq"].as_u64().unwrap() + 5);
        drop(stalled);
    });
}

#[test]
fn addresses_and_ports_in_use_get_clear_errors() {
    assert_eq!(parse_addr("8080").unwrap().to_string(), "127.0.0.1:8080");
    assert_eq!(
        parse_addr("localhost:9000").unwrap().to_string(),
        "127.0.0.1:9000"
    );
    assert_eq!(parse_addr("[::1]:80").unwrap().to_string(), "[::1]:80");
    for bad in [
        "",
        "foo",
        "127.0.0.1",
        "127.0.0.1:99999",
        "host:80",
        "localhost:x",
    ] {
        let e = parse_addr(bad).unwrap_err();
        assert!(e.contains("HOST:PORT"), "{bad}: {e}");
    }
    let taken = bind(parse_addr("127.0.0.1:0").unwrap()).unwrap();
    let e = bind(taken.local_addr().unwrap()).unwrap_err();
    assert!(e.contains("in use") && e.contains("--serve"), "{e}");
    let e = bind(parse_addr("192.0.2.1:8080").unwrap()).unwrap_err();
    assert!(e.contains("not an address of this machine"), "{e}");
}

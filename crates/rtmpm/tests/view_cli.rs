//! `rtmpm view`: what it says without a front-end, its refusals of bad flags, a recording
//! without a front-end, and the server's start and clean end on Ctrl-C.

mod common;

use common::{data, rtmpm, scratch, text};
use std::io::{BufRead, BufReader, Read, Write};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

#[test]
fn without_a_display_or_serve_it_says_how_to_watch() {
    let o = Command::new(env!("CARGO_BIN_EXE_rtmpm"))
        .args(["view", &data("small_drop.toml"), "--backend", "cpu"])
        .env_remove("DISPLAY")
        .env_remove("WAYLAND_DISPLAY")
        .output()
        .unwrap();
    let t = text(&o);
    assert!(!o.status.success());
    assert!(t.contains("no display") && t.contains("--serve"), "{t}");
    assert!(t.contains("ssh -L 8080:localhost:8080"), "{t}");
}

#[test]
fn bad_flags_are_refused_with_the_fix() {
    let scene = data("small_drop.toml");
    for (args, says) in [
        (vec!["--serve", "nonsense"], "HOST:PORT"),
        (vec!["--serve", "127.0.0.1:99999"], "HOST:PORT"),
        (vec!["--record", "movie.avi"], ".gif or .mp4"),
        (vec!["--record", "/no/such/folder/m.gif"], "does not exist"),
        (vec!["--frames", "0", "--record", "x.gif"], "at least 1"),
        (vec!["--pace", "laps:3", "--serve"], "frames:N or steps:N"),
        (vec!["--size", "5x5", "--serve"], "out of range"),
        (vec!["--quality", "0", "--serve"], "1..=100"),
    ] {
        let mut all = vec!["view", scene.as_str(), "--backend", "cpu"];
        all.extend(&args);
        let o = rtmpm(&all);
        let t = text(&o);
        assert!(!o.status.success(), "{args:?}: {t}");
        assert!(t.contains(says), "{args:?}: {t}");
    }
}

#[test]
fn a_port_in_use_is_refused_with_another_to_try() {
    let taken = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = taken.local_addr().unwrap().to_string();
    let o = rtmpm(&[
        "view",
        &data("small_drop.toml"),
        "--backend",
        "cpu",
        "--serve",
        &addr,
    ]);
    let t = text(&o);
    assert!(!o.status.success());
    assert!(
        t.contains("in use") && t.contains("choose another port"),
        "{t}"
    );
}

#[test]
fn a_recording_without_a_front_end_has_every_frame_and_keeps_existing_files() {
    let dir = scratch("view-record");
    let gif = dir.join("drop.gif");
    let gif_s = gif.display().to_string();
    let args = [
        "view",
        &data("small_drop.toml"),
        "--backend",
        "cpu",
        "--size",
        "160x90",
        "--frames",
        "3",
        "--record",
        &gif_s,
    ];
    let o = rtmpm(&args);
    let t = text(&o);
    assert!(o.status.success(), "{t}");
    assert!(t.contains("4 frames of 160x90"), "{t}");
    let bytes = std::fs::read(&gif).unwrap();
    assert_eq!(&bytes[..6], b"GIF89a");
    // The file exists now: refused without --overwrite, and left as it was.
    let o = rtmpm(&args);
    assert!(!o.status.success());
    assert!(text(&o).contains("--overwrite"), "{}", text(&o));
    assert_eq!(std::fs::read(&gif).unwrap(), bytes);
}

#[test]
fn the_server_serves_the_page_and_ends_cleanly_on_ctrl_c() {
    let mut child = Command::new(env!("CARGO_BIN_EXE_rtmpm"))
        .args([
            "view",
            &data("small_drop.toml"),
            "--backend",
            "cpu",
            "--size",
            "160x90",
        ])
        .args(["--serve", "127.0.0.1:0"])
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut err = BufReader::new(child.stderr.take().unwrap());
    let start = Instant::now();
    let mut addr = None;
    let mut said = String::new();
    while addr.is_none() && start.elapsed() < Duration::from_secs(120) {
        let mut line = String::new();
        if err.read_line(&mut line).unwrap() == 0 {
            break;
        }
        said.push_str(&line);
        if let Some(rest) = line.split("open http://").nth(1) {
            addr = rest.split('/').next().map(str::to_string);
        }
    }
    let addr = addr.unwrap_or_else(|| panic!("no address announced: {said}"));
    let mut s = std::net::TcpStream::connect(&addr).unwrap();
    write!(s, "GET / HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n").unwrap();
    let mut page = String::new();
    s.read_to_string(&mut page).unwrap();
    assert!(
        page.starts_with("HTTP/1.1 200") && page.contains("<canvas"),
        "{page}"
    );
    // Ctrl-C: it ends by itself, with its summary.
    // SAFETY: a signal to our own child process.
    unsafe { libc::kill(child.id() as libc::pid_t, libc::SIGINT) };
    let status = child.wait().unwrap();
    let mut rest = String::new();
    err.read_to_string(&mut rest).unwrap();
    assert!(status.success(), "{status}: {rest}");
    assert!(rest.contains("pictures shown"), "{rest}");
}

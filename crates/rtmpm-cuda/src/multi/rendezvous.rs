//! Where the processes of a multi-process (multi-machine) run meet: rank 0 makes the NCCL unique
//! id and hands it to every other rank, through a TCP port of rank 0 (`tcp://HOST:PORT`) or a file
//! on a shared filesystem (`file:PATH`). Any launcher works (mpirun, srun, by hand): each process
//! only needs its rank, the number of ranks and the rendezvous.

use std::io::{Read, Write};
use std::net::{TcpListener, TcpStream};
use std::path::PathBuf;
use std::time::{Duration, Instant};

const MAGIC: &[u8; 8] = b"RTMPMNCC";

/// A rendezvous address.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Rendezvous {
    /// `tcp://HOST:PORT`: rank 0 listens on PORT (all interfaces), the others connect to HOST:PORT.
    Tcp(String),
    /// `file:PATH`: rank 0 writes the id to PATH (which must not exist), the others read it.
    File(PathBuf),
}

impl std::str::FromStr for Rendezvous {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        if let Some(a) = s.strip_prefix("tcp://") {
            let (host, port) = a
                .rsplit_once(':')
                .ok_or_else(|| format!("`{s}`: expected tcp://HOST:PORT"))?;
            port.parse::<u16>()
                .map_err(|_| format!("`{s}`: the port `{port}` is not a number in 1..65535"))?;
            if host.is_empty() {
                return Err(format!(
                    "`{s}`: expected tcp://HOST:PORT (the host of rank 0)"
                ));
            }
            Ok(Rendezvous::Tcp(a.to_string()))
        } else if let Some(p) = s.strip_prefix("file:") {
            if p.is_empty() {
                return Err(format!("`{s}`: expected file:PATH"));
            }
            Ok(Rendezvous::File(p.into()))
        } else {
            Err(format!(
                "`{s}`: a rendezvous is tcp://HOST:PORT (rank 0's address) or file:PATH (on a \
                 filesystem every rank sees)"
            ))
        }
    }
}

fn timeout() -> Duration {
    Duration::from_secs(
        std::env::var("RTMPM_RENDEZVOUS_TIMEOUT")
            .ok()
            .and_then(|s| s.parse().ok())
            .unwrap_or(300),
    )
}

/// The 136-byte message: magic, number of ranks (u32 LE), 128 bytes of id... minus nothing.
fn message(ranks: usize, id: &[u8; 128]) -> Vec<u8> {
    let mut m = MAGIC.to_vec();
    m.extend_from_slice(&(ranks as u32).to_le_bytes());
    m.extend_from_slice(id);
    m
}

fn parse(m: &[u8], ranks: usize, from: &str) -> Result<[u8; 128], String> {
    if m.len() != 140 || &m[..8] != MAGIC {
        return Err(format!("{from}: not an rtmpm rendezvous message"));
    }
    let theirs = u32::from_le_bytes([m[8], m[9], m[10], m[11]]) as usize;
    if theirs != ranks {
        return Err(format!(
            "{from}: rank 0 runs with {theirs} ranks, this process with {ranks}: give every \
             process the same --nccl-ranks"
        ));
    }
    let mut id = [0u8; 128];
    id.copy_from_slice(&m[12..]);
    Ok(id)
}

impl Rendezvous {
    /// Rank 0: publish `id` and wait until every other rank has it. Other ranks: fetch it.
    pub fn exchange(
        &self,
        rank: usize,
        ranks: usize,
        id: Option<[u8; 128]>,
    ) -> Result<[u8; 128], String> {
        let deadline = Instant::now() + timeout();
        match (self, rank, id) {
            (Rendezvous::Tcp(addr), 0, Some(id)) => {
                let port = addr.rsplit_once(':').map_or("", |p| p.1);
                let l = TcpListener::bind(format!("0.0.0.0:{port}")).map_err(|e| {
                    format!("rendezvous tcp://{addr}: rank 0 cannot listen on port {port}: {e}")
                })?;
                l.set_nonblocking(true).map_err(|e| e.to_string())?;
                let msg = message(ranks, &id);
                let mut served = 0;
                while served + 1 < ranks {
                    match l.accept() {
                        Ok((mut s, _)) => {
                            s.set_nonblocking(false).map_err(|e| e.to_string())?;
                            s.write_all(&msg)
                                .map_err(|e| format!("rendezvous tcp://{addr}: {e}"))?;
                            served += 1;
                        }
                        Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {
                            if Instant::now() > deadline {
                                return Err(format!(
                                    "rendezvous tcp://{addr}: only {served} of {} other ranks came \
                                     within {:?} (RTMPM_RENDEZVOUS_TIMEOUT)",
                                    ranks - 1,
                                    timeout()
                                ));
                            }
                            std::thread::sleep(Duration::from_millis(10));
                        }
                        Err(e) => return Err(format!("rendezvous tcp://{addr}: {e}")),
                    }
                }
                Ok(id)
            }
            (Rendezvous::Tcp(addr), _, _) => loop {
                match TcpStream::connect(addr.as_str()) {
                    Ok(mut s) => {
                        let mut m = Vec::new();
                        s.set_read_timeout(Some(timeout()))
                            .map_err(|e| e.to_string())?;
                        s.read_to_end(&mut m)
                            .map_err(|e| format!("rendezvous tcp://{addr}: {e}"))?;
                        return parse(&m, ranks, &format!("rendezvous tcp://{addr}"));
                    }
                    Err(e) => {
                        if Instant::now() > deadline {
                            return Err(format!(
                                "rendezvous tcp://{addr}: rank 0 did not answer within {:?}: {e}",
                                timeout()
                            ));
                        }
                        std::thread::sleep(Duration::from_millis(50));
                    }
                }
            },
            (Rendezvous::File(path), 0, Some(id)) => {
                if path.exists() {
                    return Err(format!(
                        "rendezvous file:{}: the file exists (left by an earlier run?): remove it or \
                         give a new path",
                        path.display()
                    ));
                }
                let tmp = path.with_extension(format!("tmp{}", std::process::id()));
                std::fs::write(&tmp, message(ranks, &id))
                    .and_then(|_| std::fs::rename(&tmp, path))
                    .map_err(|e| format!("rendezvous file:{}: {e}", path.display()))?;
                // Wait for every rank's acknowledgement, then remove the files.
                let ack = |r: usize| PathBuf::from(format!("{}.ack{r}", path.display()));
                while (1..ranks).any(|r| !ack(r).exists()) {
                    if Instant::now() > deadline {
                        return Err(format!(
                            "rendezvous file:{}: not every rank read it within {:?}",
                            path.display(),
                            timeout()
                        ));
                    }
                    std::thread::sleep(Duration::from_millis(20));
                }
                let _ = std::fs::remove_file(path);
                for r in 1..ranks {
                    let _ = std::fs::remove_file(ack(r));
                }
                Ok(id)
            }
            (Rendezvous::File(path), _, _) => loop {
                if let Ok(m) = std::fs::read(path)
                    && m.len() == 140
                {
                    let id = parse(&m, ranks, &format!("rendezvous file:{}", path.display()))?;
                    std::fs::write(format!("{}.ack{rank}", path.display()), b"ok")
                        .map_err(|e| format!("rendezvous file:{}: {e}", path.display()))?;
                    return Ok(id);
                }
                if Instant::now() > deadline {
                    return Err(format!(
                        "rendezvous file:{}: rank 0 did not write it within {:?}",
                        path.display(),
                        timeout()
                    ));
                }
                std::thread::sleep(Duration::from_millis(20));
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_addresses_and_rejects_bad_ones() {
        assert_eq!(
            "tcp://node1:29500".parse::<Rendezvous>(),
            Ok(Rendezvous::Tcp("node1:29500".into()))
        );
        assert_eq!(
            "file:/shared/job7.id".parse::<Rendezvous>(),
            Ok(Rendezvous::File("/shared/job7.id".into()))
        );
        for bad in [
            "tcp://node1",
            "tcp://:80",
            "tcp://h:99999",
            "udp://x:1",
            "file:",
        ] {
            assert!(bad.parse::<Rendezvous>().is_err(), "{bad}");
        }
    }

    fn exchange_all(r: Rendezvous, ranks: usize) {
        let mut id = [0u8; 128];
        id.iter_mut()
            .enumerate()
            .for_each(|(i, b)| *b = i as u8 ^ 0x5a);
        let handles: Vec<_> = (1..ranks)
            .map(|rank| {
                let r = r.clone();
                std::thread::spawn(move || r.exchange(rank, ranks, None))
            })
            .collect();
        assert_eq!(r.exchange(0, ranks, Some(id)), Ok(id));
        for h in handles {
            assert_eq!(h.join().unwrap(), Ok(id));
        }
    }

    #[test]
    fn three_ranks_meet_through_tcp() {
        // A free port: bind port 0, read it, release it.
        let port = TcpListener::bind("127.0.0.1:0")
            .unwrap()
            .local_addr()
            .unwrap()
            .port();
        exchange_all(Rendezvous::Tcp(format!("127.0.0.1:{port}")), 3);
    }

    #[test]
    fn three_ranks_meet_through_a_file_and_leave_nothing() {
        let dir = std::env::temp_dir().join(format!("rtmpm-rdv-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("id");
        exchange_all(Rendezvous::File(path.clone()), 3);
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 0);
        // A stale file is refused by rank 0.
        std::fs::write(&path, b"old").unwrap();
        let e = Rendezvous::File(path.clone())
            .exchange(0, 2, Some([0; 128]))
            .unwrap_err();
        assert!(e.contains("exists"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_different_rank_count_is_a_clear_error() {
        let m = message(4, &[1; 128]);
        let e = parse(&m, 2, "x").unwrap_err();
        assert!(e.contains("same --nccl-ranks"), "{e}");
    }
}

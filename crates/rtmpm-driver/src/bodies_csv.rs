//! `bodies.csv`: the rigid bodies' poses and velocities at every frame of a run.

use crate::simulation::Simulation;
use anyhow::{Context, Result, bail};
use rtmpm_io::signature::BODIES_CSV_HEADER;
use rtmpm_scene::Scene;
use std::collections::BTreeMap;
use std::path::Path;

/// `bodies.csv` in the output folder: the pose and velocities of every rigid body at every
/// frame (`[[rigid_body]]`; nothing when the scene has none).
pub struct BodiesCsv {
    file: Option<std::io::BufWriter<std::fs::File>>,
    names: Vec<String>,
}

/// The rows of a previous run's `bodies.csv` that a run resumed at `frame` keeps
/// ([`KeptRows::read`]).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct KeptRows {
    /// The checkpoint's frame.
    pub frame: u64,
    /// The rows of frames up to `frame`, checked.
    pub rows: Vec<String>,
    /// The file lacks (some of) the rows of `frame` itself: they are written again from the
    /// restored poses.
    pub rewrite: bool,
}

impl BodiesCsv {
    /// The file, new (none when `writes` is false or the scene has no rigid bodies); or,
    /// resumed, the rows a previous run wrote up to the checkpoint's frame as
    /// [`KeptRows::read`] checked them, with the row of that frame written again from the
    /// restored poses when the file lacked it (later frames are written again).
    pub fn new(
        writes: bool,
        dir: &Path,
        sim: &Simulation,
        resumed: Option<KeptRows>,
    ) -> Result<BodiesCsv> {
        let names: Vec<String> = sim
            .scene
            .rigid_bodies
            .iter()
            .map(|b| b.name.clone())
            .collect();
        if !writes || names.is_empty() {
            return Ok(BodiesCsv { file: None, names });
        }
        std::fs::create_dir_all(dir)
            .with_context(|| format!("cannot create output folder {}", dir.display()))?;
        let path = dir.join("bodies.csv");
        let kept = resumed.unwrap_or_default();
        let mut text = format!("{BODIES_CSV_HEADER}\n");
        for l in &kept.rows {
            text.push_str(l);
            text.push('\n');
        }
        rtmpm_io::write_atomic(&path, text.as_bytes())
            .with_context(|| format!("cannot write {}", path.display()))?;
        let f = std::io::BufWriter::new(
            std::fs::OpenOptions::new()
                .append(true)
                .open(&path)
                .with_context(|| format!("cannot write {}", path.display()))?,
        );
        let mut csv = BodiesCsv {
            file: Some(f),
            names,
        };
        if kept.rewrite {
            csv.write(kept.frame, sim.time, sim)?;
        }
        Ok(csv)
    }

    /// The rows of frame `frame` at `time`.
    pub fn write(&mut self, frame: u64, time: f64, sim: &Simulation) -> Result<()> {
        let Some(f) = self.file.as_mut() else {
            return Ok(());
        };
        use std::io::Write;
        for (b, name) in sim.backend.rigid_bodies().iter().zip(&self.names) {
            let q = glam::Quat::from_mat3(&b.rotation);
            let (c, v, w) = (b.center, b.velocity, b.angular_velocity);
            writeln!(
                f,
                "{frame},{time},{name:?},{},{},{},{},{},{},{},{},{},{},{},{},{}",
                c.x, c.y, c.z, q.x, q.y, q.z, q.w, v.x, v.y, v.z, w.x, w.y, w.z
            )?;
        }
        f.flush()?;
        Ok(())
    }
}

impl KeptRows {
    /// The rows of `bodies.csv` at `path` a run resumed at frame `at` keeps (every row of
    /// frames up to `at`), and whether the row of frame `at` itself must be written again (from
    /// the checkpoint's poses). A file that is not rtmpm's, or has a row that cannot be read, is
    /// kept and refuses the resume; missing rows are a warning naming the frames.
    pub fn read(path: &Path, scene: &Scene, at: u64) -> Result<KeptRows> {
        let names: Vec<String> = scene
            .rigid_bodies
            .iter()
            .map(|b| format!("{:?}", b.name))
            .collect();
        let text = match std::fs::read(path) {
            Ok(bytes) => String::from_utf8(bytes).map_err(|_| {
                anyhow::anyhow!(
                    "{} is not UTF-8 text; it is kept\n  fix: move it away, and the resumed run \
                     starts a new one",
                    path.display()
                )
            })?,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                eprintln!(
                    "warning: {} is missing: the resumed run writes the rows from frame {at} on \
                     (those of frames 0 to {} are not in it)",
                    path.display(),
                    at.saturating_sub(1)
                );
                return Ok(KeptRows {
                    frame: at,
                    rows: Vec::new(),
                    rewrite: true,
                });
            }
            Err(e) => return Err(e).with_context(|| format!("cannot read {}", path.display())),
        };
        let mut lines = text.lines().enumerate();
        if lines.next().map(|(_, l)| l) != Some(BODIES_CSV_HEADER) {
            bail!(
                "{} does not start with rtmpm's header ({BODIES_CSV_HEADER}): it is not the file of \
                 this run, and it is kept\n  fix: move it away, and the resumed run starts a new one",
                path.display()
            );
        }
        // The rows of frames 0..=at, checked: 16 columns, the frame's bodies in the scene's order.
        let mut kept = Vec::new();
        // Rows counted per frame, for the frames that have rows only: the checkpoint's frame
        // number sizes nothing and bounds no loop.
        let mut per_frame: BTreeMap<u64, usize> = BTreeMap::new();
        for (i, line) in lines {
            if line.trim().is_empty() {
                continue;
            }
            let cols: Vec<&str> = line.split(',').collect();
            let bad = |why: &str| {
                anyhow::anyhow!(
                    "{}:{}: {why}: {line}\n  the file is kept; fix or remove the line, or move the \
                     file away (the resumed run then starts a new one)",
                    path.display(),
                    i + 1
                )
            };
            if cols.len() != 16 {
                return Err(bad(&format!("{} columns, not 16", cols.len())));
            }
            let frame: u64 = cols[0].parse().map_err(|_| bad("no frame number"))?;
            if frame > at {
                continue; // written again by the resumed run
            }
            if cols[1..]
                .iter()
                .enumerate()
                .any(|(k, c)| k != 1 && c.parse::<f64>().is_err())
            {
                return Err(bad("a column that is not a number"));
            }
            let slot = per_frame.entry(frame).or_insert(0);
            let k = *slot;
            if names.get(k).map(String::as_str) != Some(cols[2]) {
                return Err(bad(&format!(
                    "frame {frame} names body {} where the scene's body {k} is {}",
                    cols[2],
                    names.get(k).map_or("none (too many rows)", String::as_str)
                )));
            }
            *slot += 1;
            kept.push((frame, line.to_string()));
        }
        let rewrite_last = per_frame.get(&at) != Some(&names.len());
        if rewrite_last {
            // The checkpoint's own frame is written again from its poses (by its number as
            // parsed: a frame written `03` is frame 3).
            kept.retain(|&(frame, _)| frame != at);
        }
        let kept: Vec<String> = kept.into_iter().map(|(_, line)| line).collect();
        let lost = incomplete_before(&per_frame, at, names.len());
        if !lost.is_empty() {
            eprintln!(
                "warning: {} lacks the rows of some bodies at frames {}: they cannot be rebuilt \
                 (the checkpoint holds frame {at} only); the other rows are kept",
                path.display(),
                ranges(&lost)
            );
        }
        Ok(KeptRows {
            frame: at,
            rows: kept,
            rewrite: rewrite_last,
        })
    }
}

/// The frames before `at` whose rows are missing or incomplete (`per_frame`: rows per frame
/// that has any; `n`: bodies per frame), as spans of consecutive frames, found from the frames
/// with rows (the gaps between them are spans too), so a large `at` costs nothing.
fn incomplete_before(per_frame: &BTreeMap<u64, usize>, at: u64, n: usize) -> Vec<(u64, u64)> {
    let mut spans: Vec<(u64, u64)> = Vec::new();
    let mut add = |a: u64, b: u64| match spans.last_mut() {
        Some(last) if last.1 + 1 == a => last.1 = b,
        _ => spans.push((a, b)),
    };
    let mut next = 0;
    for (&f, &rows) in per_frame.range(..at) {
        if f > next {
            add(next, f - 1);
        }
        if rows != n {
            add(f, f);
        }
        next = f + 1;
    }
    if next < at {
        add(next, at - 1);
    }
    spans
}

/// `0..3, 7, 9..12`.
fn ranges(spans: &[(u64, u64)]) -> String {
    spans
        .iter()
        .map(|&(a, b)| {
            if a == b {
                a.to_string()
            } else {
                format!("{a}..{b}")
            }
        })
        .collect::<Vec<_>>()
        .join(", ")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scene() -> Scene {
        Scene::from_toml(
            "[domain]\nmin = [0, 0, 0]\nmax = [1, 1, 1]\ndx = 0.1\n[time]\nduration = 1\n\
             [[rigid_body]]\nname = \"a\"\nshape = \"sphere\"\ncenter = [0.5, 0.5, 0.5]\n\
             radius = 0.1\ndensity = 500\n",
            "resume",
        )
        .unwrap()
    }

    fn row(frame: u64, name: &str) -> String {
        format!("{frame},0,\"{name}\",0.5,0.5,0.5,0,0,0,1,0,0,0,0,0,0")
    }

    fn write(rows: &[String]) -> (std::path::PathBuf, std::path::PathBuf) {
        let dir = std::env::temp_dir().join(format!(
            "rtmpm-bodies-csv-{}-{}",
            std::process::id(),
            rows.len()
        ));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("bodies.csv");
        let mut t = format!("{BODIES_CSV_HEADER}\n");
        for r in rows {
            t.push_str(r);
            t.push('\n');
        }
        std::fs::write(&p, t).unwrap();
        (dir, p)
    }

    #[test]
    fn rows_up_to_the_checkpoint_are_checked() {
        let s = scene();
        let (dir, p) = write(&[row(0, "a"), row(1, "a"), row(2, "a"), row(3, "a")]);
        let KeptRows {
            rows: kept,
            rewrite: again,
            ..
        } = KeptRows::read(&p, &s, 2).unwrap();
        assert_eq!((kept.len(), again), (3, false));
        // Frame 2 missing: written again from the checkpoint.
        let (dir2, p2) = write(&[row(0, "a"), row(1, "a")]);
        assert_eq!(
            KeptRows::read(&p2, &s, 2).unwrap(),
            KeptRows {
                frame: 2,
                rows: vec![row(0, "a"), row(1, "a")],
                rewrite: true
            }
        );
        // Another body's name, or a broken row: refused.
        let (dir3, p3) = write(&[row(0, "b")]);
        let e = KeptRows::read(&p3, &s, 2).unwrap_err().to_string();
        assert!(e.contains("bodies.csv:2") && e.contains("\"b\""), "{e}");
        let _ = std::fs::write(&p3, "x,y\n");
        assert!(
            KeptRows::read(&p3, &s, 2)
                .unwrap_err()
                .to_string()
                .contains("header")
        );
        // Missing file: started again.
        assert_eq!(
            KeptRows::read(&dir3.join("none.csv"), &s, 2).unwrap(),
            KeptRows {
                frame: 2,
                rows: vec![],
                rewrite: true
            }
        );
        for d in [dir, dir2, dir3] {
            let _ = std::fs::remove_dir_all(d);
        }
    }

    /// The frames lost before the checkpoint's: gaps and frames with too few rows, merged into
    /// spans, from the frames that have rows only.
    #[test]
    fn incomplete_frames_are_spans() {
        let per_frame = BTreeMap::from([(1, 2), (2, 1), (3, 2), (6, 2), (9, 2)]);
        let lost = incomplete_before(&per_frame, 9, 2);
        assert_eq!(lost, vec![(0, 0), (2, 2), (4, 5), (7, 8)]);
        assert_eq!(ranges(&lost), "0, 2, 4..5, 7..8");
        assert!(incomplete_before(&BTreeMap::from([(0, 2)]), 1, 2).is_empty());
        assert_eq!(
            incomplete_before(&BTreeMap::new(), u64::MAX, 2),
            vec![(0, u64::MAX - 1)]
        );
    }

    /// A checkpoint's frame number bounds no loop and sizes nothing: a frame of 10^15 (a
    /// checkpoint with a valid checksum can hold any) is read at once, its rows kept, the frames
    /// after them named as lost in one span (before, the frames 0..=at were walked one by one:
    /// a hang).
    #[test]
    fn a_huge_checkpoint_frame_does_not_hang() {
        let s = scene();
        let (dir, p) = write(&[
            row(0, "a"),
            row(1, "a"),
            row(2, "a"),
            row(3, "a"),
            row(4, "a"),
        ]);
        let at = 1_000_000_000_000_000;
        let kept = KeptRows::read(&p, &s, at).unwrap();
        assert_eq!((kept.rows.len(), kept.rewrite), (5, true));
        let lost = incomplete_before(
            &BTreeMap::from([(0, 1), (1, 1), (2, 1), (3, 1), (4, 1)]),
            at,
            1,
        );
        assert_eq!(lost, vec![(5, at - 1)]);
        let _ = std::fs::remove_dir_all(dir);
    }

    /// The checkpoint's frame, incomplete, is written again: its rows are dropped by their frame
    /// number as parsed, also where the file writes it otherwise (`03` for frame 3; the fuzz
    /// target `resume` found such a row kept, compared as text, beside the frame's new rows).
    #[test]
    fn the_frame_written_again_drops_its_rows_however_its_number_is_written() {
        let s = Scene::from_toml(
            "[domain]\nmin = [0, 0, 0]\nmax = [1, 1, 1]\ndx = 0.05\n[time]\nduration = 1\n\
             [[rigid_body]]\nname = \"a\"\nshape = \"sphere\"\ncenter = [0.3, 0.5, 0.5]\n\
             radius = 0.1\ndensity = 500\n\
             [[rigid_body]]\nname = \"b\"\nshape = \"sphere\"\ncenter = [0.7, 0.5, 0.5]\n\
             radius = 0.1\ndensity = 500\n",
            "resume",
        )
        .unwrap();
        let padded = row(3, "a").replacen('3', "03", 1);
        let rows = [
            row(0, "a"),
            row(0, "b"),
            row(1, "a"),
            row(1, "b"),
            row(2, "a"),
            row(2, "b"),
            padded,
        ];
        let (dir, p) = write(&rows);
        let kept = KeptRows::read(&p, &s, 3).unwrap();
        assert!(kept.rewrite, "frame 3 lacks body b: written again");
        assert_eq!(kept.rows, rows[..6].to_vec(), "frame 3's row dropped");
        let _ = std::fs::remove_dir_all(dir);
    }
}

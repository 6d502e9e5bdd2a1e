//! The lockstep batch driver's files on CPU worlds side by side (`lockstep_support`): the output
//! folder holds each world's frames and `batch.csv` (a frozen world's frames stop at its
//! frame), and a batch resumed from a checkpoint writes the uninterrupted run's files and ends
//! as it does, bit for bit.

mod common;
mod lockstep_support;

use common::bits;
use lockstep_support::{SLUMP, SideBySide, lockstep};
use rtmpm_driver::batch::lockstep::LockstepRun;
use rtmpm_driver::batch::{BatchOptions, WorldStatus};
use rtmpm_scene::BatchScene;
use rtmpm_sim::Particles;

#[test]
fn the_output_folder_holds_each_world_and_a_frozen_world_stops_at_its_frame() {
    let dir = std::env::temp_dir().join(format!("rtmpm-lockstep-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let text = SLUMP.replace(
        "\"material[0].yield_stress\" = [20, 150, 600]",
        "\"body[0].velocity\" = [[0, 0, 0], [1e5, 0, 0], [0, 0.5, 0]]",
    );
    let options = BatchOptions {
        frames: Some(2),
        out_dir: Some(dir.clone()),
        overwrite: false,
    };
    let (_, r) = lockstep(&text, &options);
    assert_eq!(r.running(), 2);
    let csv = std::fs::read_to_string(dir.join("batch.csv")).expect("batch.csv");
    let rows: Vec<&str> = csv.lines().collect();
    assert_eq!(rows[0], "world,folder,label,status,frames,steps");
    assert!(
        rows[1].starts_with("0,world_000,") && rows[1].contains(",done,2,"),
        "{csv}"
    );
    assert!(
        rows[2].contains("frozen: simulation blew up") && rows[2].ends_with(",0,0"),
        "{csv}"
    );
    assert!(rows[3].contains(",done,2,"), "{csv}");
    let files = |w: &str| {
        let mut f: Vec<String> = std::fs::read_dir(dir.join(w))
            .expect("world folder")
            .filter_map(|e| e.ok()?.file_name().into_string().ok())
            .filter(|n| n.starts_with("frame_") && n.ends_with(".ply"))
            .collect();
        f.sort();
        f
    };
    assert_eq!(files("world_000").len(), 3, "{:?}", files("world_000"));
    assert_eq!(files("world_001"), ["frame_00000.ply"]);
    assert_eq!(files("world_002").len(), 3);
    std::fs::remove_dir_all(&dir).expect("clean up");
}

/// Every file under `dir` (relative path, bytes), the run locks aside.
fn files_under(dir: &std::path::Path) -> std::collections::BTreeMap<String, Vec<u8>> {
    let mut out = std::collections::BTreeMap::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).expect("read folder").flatten() {
            let p = e.path();
            if p.is_dir() {
                stack.push(p);
            } else if !p.ends_with(".rtmpm-run") && !p.to_string_lossy().contains(".lock") {
                let rel = p.strip_prefix(dir).expect("under").display().to_string();
                out.insert(rel, std::fs::read(&p).expect("read file"));
            }
        }
    }
    out
}

#[test]
#[cfg_attr(
    feature = "f64",
    ignore = "a checkpoint holds the particles' f32 interface state: an f64 run resumes from it \
              rounded, not bit for bit"
)]
fn a_resumed_lockstep_batch_equals_the_uninterrupted_one_bit_for_bit() {
    // World 1 blows up in frame 1 and stays frozen through the checkpoint and the resume.
    let text = SLUMP.replace(
        "\"material[0].yield_stress\" = [20, 150, 600]",
        "\"body[0].velocity\" = [[0, 0, 0], [1e5, 0, 0], [0, 0.5, 0]]",
    );
    let b = BatchScene::from_toml(&text, "wedge.toml").unwrap_or_else(|e| panic!("{e}"));
    let top = std::env::temp_dir().join(format!("rtmpm-lockstep-ckpt-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&top);
    let options = |dir: &str, frames: u64| BatchOptions {
        frames: Some(frames),
        out_dir: Some(top.join(dir)),
        overwrite: false,
    };
    let every = Some((2, text.as_str(), "wedge.toml"));
    let fresh = |dir: &str, frames: u64| {
        let backend = Box::new(SideBySide::new(&b.worlds));
        let mut r = LockstepRun::new(
            &b,
            &text,
            b.worlds[0].clone(),
            backend,
            &options(dir, frames),
        )
        .expect("batch");
        r.execute_checkpointed(every, |_, _| {}).expect("run");
        r
    };
    let whole = fresh("whole", 4);
    assert_eq!((whole.sim.frame, whole.running()), (4, 2));
    drop(fresh("cut", 2));
    let ckpt = top.join("cut").join("checkpoint_00002");
    assert!(ckpt.join("batch.toml").is_file() && ckpt.join("world_002.ckpt").is_file());
    let resume = |dir: &std::path::Path, options: &BatchOptions| {
        let side = |p: &[Particles]| {
            Ok((
                b.worlds[0].clone(),
                Box::new(SideBySide::from_particles(&b.worlds, p)),
            ))
        };
        LockstepRun::resume(&b, &text, dir, side, options)
    };
    let mut again = resume(&ckpt, &options("cut", 4)).expect("resume");
    assert_eq!((again.sim.frame, again.sim.step), (2, 100));
    assert!(matches!(
        again.worlds[1].status,
        WorldStatus::Frozen { frame: 0, .. }
    ));
    again
        .execute_checkpointed(every, |_, _| {})
        .expect("run on");
    for w in 0..3 {
        assert_eq!(
            bits(again.worlds[w].particles()),
            bits(whole.worlds[w].particles()),
            "world {w}"
        );
    }
    let (a, c) = (
        files_under(&top.join("whole")),
        files_under(&top.join("cut")),
    );
    assert_eq!(a.keys().collect::<Vec<_>>(), c.keys().collect::<Vec<_>>());
    assert!(
        a.contains_key("checkpoint_00004/world_000.ckpt"),
        "{:?}",
        a.keys()
    );
    for (k, v) in &a {
        assert!(
            c[k] == *v,
            "{k} differs between the resumed and the uninterrupted run"
        );
    }
    // A checkpoint whose running worlds are at different times cannot share one clock.
    let mut split = resume(&ckpt, &BatchOptions::default()).expect("resume without files");
    split.write_first_frame().expect("read");
    let start = b.worlds[0].sample_particles().expect("sample");
    split.reset_worlds(vec![(0, start)]).expect("reset world 0");
    let odd = top.join("odd");
    split
        .checkpoint(&odd, &text, "wedge.toml")
        .expect("checkpoint");
    let e = resume(&odd, &BatchOptions::default())
        .err()
        .expect("refused")
        .to_string();
    assert!(
        e.contains("different times") && e.contains("--backend cpu"),
        "{e}"
    );
    std::fs::remove_dir_all(&top).expect("clean up");
}

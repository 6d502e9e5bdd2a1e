//! BGEO input (a body's particle file, `shape = "particles"` with a `.bgeo` or `.bgeo.gz`):
//! any bytes give points or an error naming the file, never a panic, a hang or an allocation
//! beyond what the file holds. The reader takes a path, so each input is written to a file of
//! this process first. First byte even: the rest is the file as is; odd: the rest gzip-compressed
//! (the `.bgeo.gz` path, whose expansion is bounded).
#![no_main]
use libfuzzer_sys::fuzz_target;
use rtmpm_io::bgeo::{BgeoValues, read_bgeo};
use rtmpm_io::points::read_points;
use std::io::Write;
use std::path::PathBuf;
use std::sync::OnceLock;

fn file(gz: bool) -> &'static PathBuf {
    static PLAIN: OnceLock<PathBuf> = OnceLock::new();
    static GZ: OnceLock<PathBuf> = OnceLock::new();
    let (cell, ext) = if gz { (&GZ, "bgeo.gz") } else { (&PLAIN, "bgeo") };
    cell.get_or_init(|| std::env::temp_dir().join(format!("rtmpm-fuzz-{}.{ext}", std::process::id())))
}

fuzz_target!(|data: &[u8]| {
    let Some((&mode, rest)) = data.split_first() else {
        return;
    };
    let gz = mode % 2 == 1;
    let bytes = if gz {
        let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
        e.write_all(rest).expect("gzip");
        e.finish().expect("gzip")
    } else {
        rest.to_vec()
    };
    let path = file(gz);
    std::fs::write(path, &bytes).expect("write the input");
    if let Ok(d) = read_bgeo(path) {
        let n = d.positions.len();
        // No more points than the (expanded) bytes could describe: 12 bytes a position.
        assert!(n <= rest.len() / 12 + 1, "{n} points from {} bytes", rest.len());
        for a in &d.attributes {
            let len = match &a.values {
                BgeoValues::Float(v) => v.len(),
                BgeoValues::Int(v) => v.len(),
            };
            assert_eq!(len, n * a.size, "attribute {}", a.name);
        }
    }
    if let Ok(p) = read_points(path) {
        // What a body starts from: finite, one value per point, positive volumes and masses.
        assert!(p.positions.iter().all(|x| x.is_finite()));
        let n = p.positions.len();
        assert!(p.velocities.as_ref().is_none_or(|v| v.len() == n));
        for c in [&p.volumes, &p.masses].into_iter().flatten() {
            assert!(c.len() == n && c.iter().all(|&x| x.is_finite() && x > 0.0));
        }
    }
});

//! VTU and PVD readers: any text gives data or an error, never a panic.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    if let Ok(d) = rtmpm_io::vtu::parse_vtu(text) {
        assert_eq!(d.points.len(), d.num_points);
    }
    if let Ok(entries) = rtmpm_io::vtu::parse_pvd(text) {
        assert!(entries.iter().all(|(t, _)| t.is_finite()));
    }
});

//! PLY reader: any bytes give columns or an error, never a panic or an allocation beyond the
//! body the file holds.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(d) = rtmpm_io::ply::parse_ply(data) {
        for (_, c) in &d.columns {
            assert_eq!(c.len(), d.count);
        }
        // The body holds every value: no more vertices than bytes.
        assert!(d.count <= data.len());
    }
});

//! Scene parser and validator: any text gives a scene or a positioned error, never a panic,
//! a hang or a huge allocation; a valid scene's budget and warnings (every velocity source of
//! the step: colliders, keyframes, rigid bodies, emitters, gravity) are computed.
#![no_main]
use libfuzzer_sys::fuzz_target;
use rtmpm_scene::{Scene, Budget};

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    match Scene::from_toml(text, "<fuzz>") {
        Ok(scene) => {
            let b = Budget::estimate(&scene, None);
            let _ = b.refusals(Some(1 << 34), Some(1 << 40), true);
            let _ = scene.warnings();
        }
        Err(e) => {
            // A clear error says where: a line or a field.
            assert!(e.line.is_some() || e.field.is_some(), "unplaced error: {e}");
        }
    }
});

//! `[batch]`: parsing, the expansion into world scenes, and the errors of bad batches.

use super::sweep::{Batch, MAX_WORLDS};
use crate::scene::Scene;
use crate::{BatchScene, Budget, SceneError};
use rtmpm_physics::material::Model;

/// A small slump: one Herschel-Bulkley column.
const BASE: &str = r#"name = "slump"
[domain]
min = [0.0, 0.0, 0.0]
max = [0.5, 0.5, 0.5]
dx = 0.03125
[time]
duration = 0.1
fps = 20
[[material]]
name = "mud"
type = "herschel_bulkley"
density = 1600.0
bulk_modulus = 1e5
shear_modulus = 1e4
yield_stress = 250.0
consistency = 10.0
[[body]]
material = "mud"
shape = "box"
min = [0.2, 0.1, 0.2]
max = [0.3, 0.2, 0.3]
particles_per_cell = 8
[output]
formats = ["ply"]
"#;

fn batch(tail: &str) -> Result<BatchScene, SceneError> {
    BatchScene::from_toml(&format!("{BASE}{tail}"), "wedge.toml")
}

fn yield_stress(s: &Scene) -> f64 {
    match &s.materials[0].model {
        Model::HerschelBulkley(h) => h.yield_stress as f64,
        other => panic!("{other:?}"),
    }
}

#[test]
fn a_scene_without_batch_is_one_world() {
    let b = batch("").unwrap();
    assert_eq!(b.count(), 1);
    assert!(b.batch.is_none());
    assert_eq!(yield_stress(&b.worlds[0]), 250.0);
}

#[test]
fn a_linear_range_spans_the_worlds_ends_included() {
    let b = batch(
        "[batch]\ncount = 4\n[batch.sweep]\n\"material[0].yield_stress\" = { from = 50, to = 500 }\n",
    )
    .unwrap();
    let got: Vec<f64> = b.worlds.iter().map(yield_stress).collect();
    assert_eq!(got, vec![50.0, 200.0, 350.0, 500.0]);
    // The file's scene is kept as written.
    assert_eq!(yield_stress(&b.base), 250.0);
    assert_eq!(b.label(1), "material[0].yield_stress = 200");
}

#[test]
fn a_log_range_is_even_in_the_logarithm() {
    let b = batch(
        "[batch]\ncount = 3\n[batch.sweep]\n\"material[0].yield_stress\" = { from = 10, to = 1000, spacing = \"log\" }\n",
    )
    .unwrap();
    let got: Vec<f64> = b.worlds.iter().map(yield_stress).collect();
    assert_eq!(got[0], 10.0);
    assert!((got[1] - 100.0).abs() < 1e-3, "{got:?}");
    assert_eq!(got[2], 1000.0);
    let b = batch(
        "[batch]\ncount = 16\n[batch.sweep]\n\"material[0].yield_stress\" = { from = 25, to = 1600, spacing = \"log\" }\n",
    )
    .unwrap();
    assert_eq!(b.label(1), "material[0].yield_stress = 32.99");
    assert_eq!(b.label(14), "material[0].yield_stress = 1213");
}

#[test]
fn per_world_gravity_by_component_or_by_vector() {
    let b = batch("[batch]\ncount = 2\n[batch.sweep]\n\"gravity[1]\" = [-9.81, -1.62]\n").unwrap();
    assert_eq!(b.worlds[0].gravity.y, -9.81);
    assert_eq!(b.worlds[1].gravity.y, -1.62);
    assert_eq!(b.worlds[1].gravity.x, 0.0);
    let text = BASE.replace(
        "name = \"slump\"",
        "name = \"slump\"\ngravity = [0.0, -9.81, 0.0]",
    );
    let b = BatchScene::from_toml(
        &format!("{text}[batch]\ncount = 3\n[batch.sweep]\ngravity = {{ from = [0, -9.81, 0], to = [1, -1, 0] }}\n"),
        "w.toml",
    )
    .unwrap();
    assert_eq!(b.worlds[1].gravity.x, 0.5);
    assert_eq!(b.worlds[2].gravity.y, -1.0);
    assert_eq!(b.label(2), "gravity = [1, -1, 0]");
}

#[test]
fn an_absent_optional_field_can_be_swept() {
    let b = batch("[batch]\ncount = 2\n[batch.sweep]\n\"time.damping\" = [0.0, 0.5]\n").unwrap();
    assert_eq!(b.worlds[0].time.damping.rate, 0.0);
    assert_eq!(b.worlds[1].time.damping.rate, 0.5);
}

#[test]
fn several_sweeps_apply_together_and_the_rest_stays() {
    let b = batch(
        "[batch]\ncount = 2\n[batch.sweep]\n\"material[0].yield_stress\" = [1, 2]\n\"body[0].max[1]\" = [0.15, 0.2]\n",
    )
    .unwrap();
    assert_eq!(yield_stress(&b.worlds[1]), 2.0);
    assert_eq!(b.worlds[0].bodies[0].shape.bounds().1.y, 0.15);
    assert_eq!(b.worlds[1].bodies[0].shape.bounds().1.y, 0.2);
    assert_eq!(b.worlds[0].dx, b.worlds[1].dx);
    assert_eq!(
        b.label(0),
        "material[0].yield_stress = 1, body[0].max[1] = 0.15"
    );
}

#[test]
fn expand_is_a_pure_function_of_the_table() {
    let text = format!(
        "{BASE}[batch]\ncount = 3\n[batch.sweep]\n\"material[0].consistency\" = [1, 2, 3]\n"
    );
    let table: toml::Table = toml::from_str(&text).unwrap();
    let b = Batch::parse(&table["batch"]).unwrap();
    let once = b.expand(&table).unwrap();
    assert_eq!(once, b.expand(&table).unwrap());
    assert_eq!(once.len(), 3);
    for (w, t) in once.iter().enumerate() {
        assert!(t.get("batch").is_none());
        let m = &t["material"].as_array().unwrap()[0];
        assert_eq!(m["consistency"], toml::Value::Float(w as f64 + 1.0));
        // Everything else is the file's (and the default gravity it leaves out).
        assert_eq!(
            t["gravity"],
            toml::Value::try_from([0.0, -9.81, 0.0]).unwrap()
        );
        let mut rest = t.clone();
        rest.remove("gravity");
        let mut base = table.clone();
        base.remove("batch");
        for x in [&mut rest, &mut base] {
            x["material"].as_array_mut().unwrap()[0]
                .as_table_mut()
                .unwrap()
                .remove("consistency");
        }
        assert_eq!(rest, base);
    }
}

/// The error of a batch tail, as printed.
fn error(tail: &str) -> String {
    batch(tail).expect_err(tail).to_string()
}

#[test]
fn bad_counts_are_refused_with_the_fix() {
    let e = error("[batch]\ncount = 0\n");
    assert!(
        e.contains("field `batch.count`") && e.contains("at least one world"),
        "{e}"
    );
    assert!(e.starts_with("wedge.toml:"), "{e}");
    assert!(e.contains("fix:"), "{e}");
    let e = error("[batch]\ncount = -3\n");
    assert!(e.contains("at least one world"), "{e}");
    let e = error("[batch]\ncount = 2.5\n");
    assert!(e.contains("whole number"), "{e}");
    let e = error("[batch]\ncount = 1000000000000\n");
    assert!(
        e.contains("1000000000000") && e.contains(&MAX_WORLDS.to_string()),
        "{e}"
    );
    let e = error("[batch]\n");
    assert!(e.contains("needs `count`"), "{e}");
    let e = error("[batch]\ncount = 2\nworlds = 3\n");
    assert!(e.contains("unknown field `worlds`"), "{e}");
    // Line of the count: the base has 24 lines, [batch] is line 25.
    let e = error("[batch]\ncount = 0\n");
    assert!(e.starts_with("wedge.toml:26:1:"), "{e}");
}

#[test]
fn many_copies_of_a_scene_are_refused_before_they_are_made() {
    let text = format!("{BASE}{}[batch]\ncount = 60000\n", "#".repeat(8000) + "\n");
    let e = BatchScene::from_toml(&text, "big.toml")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("60000 worlds") && e.contains("of scene text"),
        "{e}"
    );
}

#[test]
fn unknown_and_non_numeric_fields_are_refused() {
    let e = error("[batch]\ncount = 2\n[batch.sweep]\n\"material[3].yield_stress\" = [1, 2]\n");
    assert!(
        e.contains("unknown field") && e.contains("has 1 entries"),
        "{e}"
    );
    assert!(
        e.contains("field `batch.sweep.\"material[3].yield_stress\"`"),
        "{e}"
    );
    assert!(e.starts_with("wedge.toml:28:1:"), "{e}");
    let e = error("[batch]\ncount = 2\n[batch.sweep]\n\"solver.flip\" = [0.1, 0.2]\n");
    assert!(e.contains("no `solver`"), "{e}");
    // A misspelt field of a table the file has: the scene's own check names it.
    let e = error("[batch]\ncount = 2\n[batch.sweep]\n\"material[0].yield_stres\" = [1, 2]\n");
    assert!(
        e.contains("no such field") && e.contains("yield_stres"),
        "{e}"
    );
    // A field the scene knows but the file leaves out, refused for its type: the world's
    // error with the scene's reason, not "no such field".
    let e = error("[batch]\ncount = 2\n[batch.sweep]\n\"body[0].sampling\" = [1, 2]\n");
    assert!(
        !e.contains("no such field") && e.contains("world 0 (body[0].sampling = 1) is refused"),
        "{e}"
    );
    let e = error("[batch]\ncount = 2\n[batch.sweep]\n\"material[0].type\" = [1, 2]\n");
    assert!(
        e.contains("only numbers can be swept") && e.contains("herschel_bulkley"),
        "{e}"
    );
    let e = error("[batch]\ncount = 2\n[batch.sweep]\n\"body[0]\" = [1, 2]\n");
    assert!(e.contains("only numbers") && e.contains("a table"), "{e}");
    let e = error("[batch]\ncount = 2\n[batch.sweep]\n\"body[0].min\" = [1, 2]\n");
    assert!(e.contains("vector of 3 numbers"), "{e}");
    let e = error("[batch]\ncount = 2\n[batch.sweep]\n\"body[0].particles_per_cell\" = [8, 8.5]\n");
    assert!(
        e.contains("whole number") && e.contains("world 1 would get 8.5"),
        "{e}"
    );
    let e = error("[batch]\ncount = 2\n[batch.sweep]\n\"material[0.x\" = [1, 2]\n");
    assert!(e.contains("not a field path"), "{e}");
}

#[test]
fn bad_sweep_values_are_refused() {
    let e = error("[batch]\ncount = 3\n[batch.sweep]\n\"material[0].yield_stress\" = [1, 2]\n");
    assert!(e.contains("2 values and the batch 3 worlds"), "{e}");
    let e = error("[batch]\ncount = 2\n[batch.sweep]\n\"material[0].yield_stress\" = [1, \"2\"]\n");
    assert!(e.contains("world 1 must be a number"), "{e}");
    let e = error("[batch]\ncount = 2\n[batch.sweep]\n\"material[0].yield_stress\" = [1, nan]\n");
    assert!(e.contains("finite"), "{e}");
    let e =
        error("[batch]\ncount = 2\n[batch.sweep]\n\"material[0].yield_stress\" = { from = 1 }\n");
    assert!(e.contains("no `to`"), "{e}");
    let e = error(
        "[batch]\ncount = 2\n[batch.sweep]\n\"material[0].yield_stress\" = { from = 0, to = 5, spacing = \"log\" }\n",
    );
    assert!(e.contains("above 0"), "{e}");
    let e = error("[batch]\ncount = 2\n[batch.sweep]\n\"material[0].yield_stress\" = 5\n");
    assert!(e.contains("a list or a range"), "{e}");
    // A value the scene refuses names the world, its value and the scene's reason.
    let e =
        error("[batch]\ncount = 3\n[batch.sweep]\n\"material[0].yield_stress\" = [10, -5, 20]\n");
    assert!(
        e.contains("world 1 (material[0].yield_stress = -5) is refused")
            && e.contains("material[0].yield_stress"),
        "{e}"
    );
    assert!(e.starts_with("wedge.toml:28:1:"), "{e}");
    let e = error("[batch]\ncount = 2\n[batch]\ncount = 3\n");
    assert!(e.contains("wedge.toml"), "{e}");
}

#[test]
fn the_budget_sums_the_worlds() {
    let one = batch("").unwrap().budget(None);
    let b = batch("[batch]\ncount = 5\n").unwrap();
    let five = b.budget(None);
    assert_eq!(five.particles, 5 * one.particles);
    assert_eq!(five.host_bytes, 5 * one.host_bytes);
    assert_eq!(five.steps, one.steps);
    let refusal = b
        .memory_refusal(&five, Some(2 * one.host_bytes + 1))
        .unwrap();
    assert!(
        refusal.contains("5 worlds") && refusal.contains("about 2 worlds fit"),
        "{refusal}"
    );
    assert!(b.memory_refusal(&five, Some(five.host_bytes)).is_none());
}

#[test]
fn each_world_counts_its_fixed_host_memory() {
    // A world's own state (scene, simulation, backend, output) is tens of KiB beside its
    // particles and grid: it decides the memory of a batch of tiny worlds.
    let b = batch("[batch]\ncount = 16\n").unwrap();
    let each = Budget::estimate(&b.worlds[0], None);
    let all = b.budget(None);
    assert_eq!(
        all.host_bytes,
        16 * (each.host_bytes + super::scene::HOST_BYTES_PER_WORLD)
    );
    let scaled = super::scaled_budget(&each, 16);
    assert_eq!(scaled.host_bytes, all.host_bytes);
}

#[test]
fn one_scene_of_a_batch_file_is_refused_with_the_batch_api() {
    let text = format!("{BASE}\n[batch]\ncount = 4\n");
    let e = Scene::from_toml(&text, "wedge.toml").unwrap_err();
    assert_eq!(e.field.as_deref(), Some("batch"));
    assert_eq!(e.line, Some(BASE.lines().count() + 2), "{e}");
    assert!(e.message.contains("a [batch] of 4 worlds"), "{e}");
    assert!(
        e.hint
            .as_deref()
            .unwrap_or("")
            .contains("BatchScene::from_file"),
        "{e}"
    );
    // From a file too; the batch readers take it.
    let dir = std::env::temp_dir().join(format!("rtmpm-batch-refusal-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("wedge.toml");
    std::fs::write(&path, &text).unwrap();
    let e = Scene::from_file(&path).unwrap_err();
    assert!(e.message.contains("a [batch] of 4 worlds"), "{e}");
    assert_eq!(BatchScene::from_file(&path).unwrap().count(), 4);
    std::fs::remove_dir_all(&dir).unwrap();
    assert_eq!(
        BatchScene::from_toml(&text, "wedge.toml").unwrap().count(),
        4
    );
    // A scene that only names a batch elsewhere is one scene.
    let named = BASE.replace("name = \"slump\"", "name = \"batch\"");
    assert!(Scene::from_toml(&named, "s.toml").is_ok());
}

#[test]
fn sweeps_of_one_field_twice_are_refused() {
    let e = error(
        "[batch]\ncount = 2\n[batch.sweep]\n\"gravity[1]\" = [-1, -2]\ngravity = [[0, -1, 0], [0, -3, 0]]\n",
    );
    assert!(
        e.contains("sets the same field as the sweep") && e.contains("gravity[1]"),
        "{e}"
    );
    // Two components of one vector are two fields.
    let b = batch(
        "[batch]\ncount = 2\n[batch.sweep]\n\"gravity[0]\" = [1, 2]\n\"gravity[1]\" = [-1, -2]\n",
    )
    .unwrap();
    assert_eq!(b.worlds[1].gravity.to_array(), [2.0, -2.0, 0.0]);
}

#[test]
fn the_frame_rate_and_duration_are_the_files() {
    for field in ["time.fps", "time.duration"] {
        let e = error(&format!(
            "[batch]\ncount = 2\n[batch.sweep]\n\"{field}\" = [10, 20]\n"
        ));
        assert!(
            e.contains(&format!("`{field}` is the same in every world")) && e.contains("fix:"),
            "{e}"
        );
    }
    // A time step field differs per world.
    let b = batch("[batch]\ncount = 2\n[batch.sweep]\n\"time.max_dt\" = [1e-3, 2e-3]\n").unwrap();
    assert_eq!(b.count(), 2);
}

#[test]
fn whole_numbers_beyond_exact_f64_and_labels_beyond_f32() {
    let e =
        error("[batch]\ncount = 2\n[batch.sweep]\n\"body[0].particles_per_cell\" = [8, 1e21]\n");
    assert!(e.contains("world 1 would get 1e21"), "{e}");
    // A value past f32's range is labelled as written, not as `inf`.
    let e = error("[batch]\ncount = 2\n[batch.sweep]\n\"material[0].density\" = [1000, 1e40]\n");
    assert!(
        e.contains("material[0].density = 1e40") && !e.contains("inf)"),
        "{e}"
    );
    let b = batch("[batch]\ncount = 2\n[batch.sweep]\n\"time.max_dt\" = [1e-12, 2e-3]\n\"gravity[1]\" = [-3e9, -9.81]\n")
        .unwrap();
    assert_eq!(b.label(0), "time.max_dt = 1e-12, gravity[1] = -3e9");
    assert_eq!(b.label(1), "time.max_dt = 0.002, gravity[1] = -9.81");
}

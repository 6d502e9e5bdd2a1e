//! Scene tests of the settings tables: `[time]` damping and `[solver]`, and tables that are
//! missing, integers too big for their field and names that need escaping.

use super::*;

#[test]
fn settling_damping() {
    let s =
        parse(&BASE.replacen("[time]", "[time]\ndamping = 20.0\ndamping_until = 0.5", 1)).unwrap();
    let d = s.time.damping;
    assert!((d.factor(1e-3, 0.1) - 0.98).abs() < 1e-6);
    assert_eq!(d.factor(1e-3, 0.5), 1.0);
    assert_eq!(parse(BASE).unwrap().time.damping.factor(1e-3, 0.0), 1.0);
    parse_err(
        &BASE.replacen("[time]", "[time]\ndamping = -1.0", 1),
        "time.damping",
    );
}

#[test]
fn solver_table_defaults_and_values() {
    use rtmpm_physics::transfer::{SolverSettings, Transfer, Update};
    // No [solver]: MLS-MPM/APIC, exactly today's behaviour.
    assert_eq!(parse(BASE).unwrap().solver, SolverSettings::default());
    let with = |t: &str| parse(&format!("{BASE}[solver]\n{t}\n"));
    let s = with("transfer = \"gimp\"").unwrap().solver;
    assert_eq!(
        (s.transfer, s.update, s.flip),
        (Transfer::Gimp, Update::Usl, 1.0)
    );
    let s = with("transfer = \"mpm-linear\"\nupdate = \"musl\"\nflip = 0.25")
        .unwrap()
        .solver;
    assert_eq!(
        (s.transfer, s.update, s.flip),
        (Transfer::MpmLinear, Update::Musl, 0.25)
    );
    assert_eq!(
        with("transfer = \"mls\"").unwrap().solver.transfer,
        Transfer::Mls
    );
    let s = with("transfer = \"ck-mpm\"").unwrap().solver;
    assert_eq!(
        (s.transfer, s.update, s.flip),
        (Transfer::CkMpm, Update::Usl, 0.0)
    );
}

#[test]
fn solver_table_errors_name_the_field_line_and_allowed_values() {
    let with = |t: &str| {
        let text = format!("{BASE}[solver]\n{t}\n");
        let e = parse(&text).expect_err(t);
        assert!(e.line.is_some() && e.hint.is_some(), "{e}");
        (e, text)
    };
    let (e, text) = with("transfer = \"flip\"");
    assert_eq!(e.line, Some(line_of(&text, "transfer = \"flip\"")), "{e}");
    let msg = e.to_string();
    for allowed in ["mls", "gimp", "mpm-linear", "ck-mpm"] {
        assert!(msg.contains(allowed), "{msg}");
    }
    let (e, _) = with("transfer = \"gimp\"\nupdate = \"usf\"");
    assert!(e.to_string().contains("musl"), "{e}");
    let (e, text) = with("transfer = \"gimp\"\nflip = 1.5");
    assert_eq!(e.field.as_deref(), Some("solver.flip"));
    assert_eq!(e.line, Some(line_of(&text, "flip = 1.5")));
    let (e, _) = with("flip = 0.5");
    assert_eq!(
        e.field.as_deref(),
        Some("solver.flip"),
        "flip with mls: {e}"
    );
    let (e, _) = with("update = \"musl\"");
    assert_eq!(
        e.field.as_deref(),
        Some("solver.update"),
        "musl with mls: {e}"
    );
    // CK-MPM is MLS-MPM/APIC on two grids: no MUSL, no FLIP blend.
    let (e, _) = with("transfer = \"ck-mpm\"\nupdate = \"musl\"");
    assert_eq!(e.field.as_deref(), Some("solver.update"), "{e}");
    assert!(e.to_string().contains("ck-mpm"), "{e}");
    let (e, _) = with("transfer = \"ck-mpm\"\nflip = 0.5");
    assert_eq!(e.field.as_deref(), Some("solver.flip"), "{e}");
    let (e, _) = with("transfer = \"gimp\"\nfip = 0.5");
    assert!(e.to_string().contains("fip"), "{e}");
}

/// Rigid bodies with a transfer that does not couple them (CK-MPM's two grids, MUSL's second
/// grid update): refused by the scene, naming the solver field, its line and the body, not
/// accepted by `rtmpm check` and then refused by the backend.
#[test]
fn rigid_bodies_with_ck_mpm_or_musl_are_refused_naming_the_solver_field() {
    let body = "[[rigid_body]]\nname = \"crate\"\nshape = \"box\"\nmin = [0.6, 0.6, 0.6]\n\
                max = [0.7, 0.7, 0.7]\ndensity = 500.0\n";
    for (solver, field, line) in [
        (
            "transfer = \"ck-mpm\"",
            "solver.transfer",
            "transfer = \"ck-mpm\"",
        ),
        (
            "transfer = \"gimp\"\nupdate = \"musl\"",
            "solver.update",
            "update = \"musl\"",
        ),
    ] {
        let text = format!("{BASE}[solver]\n{solver}\n{body}");
        let e = parse(&text).expect_err(solver);
        assert_eq!(e.field.as_deref(), Some(field), "{e}");
        assert_eq!(e.line, Some(line_of(&text, line)), "{e}");
        assert!(e.to_string().contains("rigid_body[0] `crate`"), "{e}");
        // The same transfer without bodies, and the bodies with the default transfer, are taken.
        parse(&format!("{BASE}[solver]\n{solver}\n")).expect(solver);
    }
    parse(&format!("{BASE}{body}")).expect("rigid bodies with mls");
}

/// Messages for hostile inputs: the table that is missing, the field of an
/// integer too large for 64 bits, a name that would climb out of `out/`.
#[test]
fn missing_tables_big_integers_and_escaping_names_are_named() {
    let base = "[domain]\nmin = [0, 0, 0]\nmax = [1, 1, 1]\ndx = 0.1\n[time]\nduration = 1\n";
    let e = Scene::from_toml("name = \"x\"\n[time]\nduration = 1\n", "s").unwrap_err();
    assert_eq!(e.field.as_deref(), Some("domain"), "{e}");
    assert!(e.hint.unwrap().contains("[domain]"));
    let e = Scene::from_toml(
        "[domain]\nmin = [0, 0, 0]\nmax = [1, 1, 1]\n[time]\nduration = 1\n",
        "s",
    )
    .unwrap_err();
    assert_eq!(e.field.as_deref(), Some("domain.dx"), "{e}");
    let e = Scene::from_toml(&format!("seed = 123456789012345678901234\n{base}"), "s").unwrap_err();
    assert_eq!(e.field.as_deref(), Some("seed"), "{e}");
    assert!(e.hint.unwrap().contains("18446744073709551615"));
    for name in ["../../evil", "a/b", "..", ".hidden", "", "a\u{7}b"] {
        let e = Scene::from_toml(&format!("name = {name:?}\n{base}"), "s").unwrap_err();
        assert_eq!(e.field.as_deref(), Some("name"), "{name}: {e}");
    }
    let e = Scene::from_toml(&format!("{base}[output]\ndir = \"out/../../x\"\n"), "s").unwrap_err();
    assert_eq!(e.field.as_deref(), Some("output.dir"), "{e}");
    assert!(Scene::from_toml(&format!("name = \"ok-name_1\"\n{base}"), "s").is_ok());
}

/// A field of a shape that the table does not allow (a half-space rigid body, a mesh emitter)
/// is reported as the shape not allowed there, with the table's shapes; a field of another
/// shape on an allowed shape is named as not that shape's.
#[test]
fn a_shape_the_table_does_not_allow_is_named() {
    let e = parse(&format!(
        "{BASE}[[rigid_body]]\nshape = \"half_space\"\npoint = [0.0, 0.1, 0.0]\nnormal = [0.0, 1.0, \
         0.0]\ndensity = 500.0\n"
    ))
    .unwrap_err();
    assert_eq!(e.field.as_deref(), Some("rigid_body[0].shape"), "{e}");
    let text = e.to_string();
    assert!(
        text.contains("a rigid body cannot be a half-space")
            && text.contains("\"box\" (min, max), \"sphere\" (center, radius), \"cylinder\"")
            && text.contains("or \"mesh\""),
        "{text}"
    );
    let e = parse(&format!(
        "{BASE}[[emitter]]\nmaterial = \"jelly\"\nshape = \"mesh\"\nfile = \"m.obj\"\nrate = 10.0\n"
    ))
    .unwrap_err();
    assert_eq!(e.field.as_deref(), Some("emitter[0].shape"), "{e}");
    let text = e.to_string();
    assert!(
        text.contains("an emitter cannot be a mesh")
            && text.contains("\"sphere\" (center, radius) or \"cylinder\""),
        "{text}"
    );
    let e = parse(&format!(
        "{BASE}[[rigid_body]]\nshape = \"box\"\nmin = [0.6, 0.6, 0.6]\nmax = [0.7, 0.7, 0.7]\n\
         density = 500.0\nnormal = [0.0, 1.0, 0.0]\n"
    ))
    .unwrap_err();
    assert_eq!(e.field.as_deref(), Some("rigid_body[0].normal"), "{e}");
    assert!(
        e.to_string()
            .contains("`normal` is not a parameter of shape \"box\""),
        "{e}"
    );
}

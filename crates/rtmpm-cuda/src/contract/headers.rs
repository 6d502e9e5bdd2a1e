//! The device code generated from the contract: `contract.cuh` ([`prelude`]), the material
//! registry ([`material_registry`]) and the layout checks ([`layout_asserts`]).

use super::constants::*;
use super::layout::*;
use super::render::*;
use super::state_layout::StateLayout;
use rtmpm_physics::boundary::Condition;
use rtmpm_physics::material::Model;
use rtmpm_physics::transfer::{Transfer, Update};
use std::fmt::Write;
use std::mem::{offset_of, size_of};

// ---------------------------------------------------------------------------------------------
// Generated device code.

/// A struct's name on the device, size and field offsets.
struct Layout {
    name: &'static str,
    size: usize,
    fields: Vec<(&'static str, usize)>,
}

macro_rules! layout {
    ($t:ty, $name:literal, [$($f:ident),* $(,)?]) => {
        Layout {
            name: $name,
            size: size_of::<$t>(),
            fields: vec![$((stringify!($f), offset_of!($t, $f))),*],
        }
    };
}

fn layouts<R: GpuReal>() -> Vec<Layout> {
    vec![
        layout!(
            Ctx,
            "Ctx",
            [
                state,
                scratch,
                grid,
                grid_next,
                grid_aux,
                grid_aux_next,
                ctl,
                scalars,
                step,
                poses,
                materials,
                colliders,
                mesh_values,
                hash_keys,
                hash_values,
                block_coords,
                neighbors,
                hist,
                scan_sums,
                pkey,
                prank,
                warps,
                boundary,
                shared_pblock,
                bodies,
                body_exchange,
                tool,
                n_cells,
                wall_thickness,
                wall_cond,
                n,
                cap,
                gblock_cap,
                pblock_cap,
                hash_cap,
                warp_cap,
                n_colliders,
                n_buckets,
                warp_reduce,
                warp_sort,
                transfer,
                update,
                always_rebuild,
                n_bodies
            ]
        ),
        layout!(
            Scalars<R>,
            "Scalars",
            [
                origin,
                dx,
                inv_dx,
                domain_min,
                domain_max,
                wall_friction,
                flip
            ]
        ),
        layout!(StepParams<R>, "StepParams", [dt, t, gravity, damping]),
        layout!(MaterialGpu<R>, "MaterialGpu", [p, kind, pad]),
        layout!(
            ColliderPoses,
            "ColliderPoses",
            [rot, pivot, velocity, omega]
        ),
        layout!(
            GpuColliderPose,
            "GpuColliderPose",
            [rot, pivot, velocity, omega]
        ),
        layout!(
            GpuCollider,
            "GpuCollider",
            [kind, cond, friction, mesh_offset, pivot, p, dims, pad]
        ),
        layout!(
            GpuBody,
            "GpuBody",
            [shape, rot, center, velocity, omega, bound, dynamic]
        ),
        layout!(GpuTool, "GpuTool", [shape, velocity, active]),
        layout!(
            RenderParams,
            "RenderParams",
            [
                keys,
                image,
                shadow,
                field,
                scratch,
                objects,
                palette,
                eye,
                fwd,
                right,
                up,
                focal,
                cx,
                cy,
                radius,
                near,
                eps1,
                range,
                floor_y,
                bounds_lo,
                bounds_hi,
                light,
                object_rgb,
                shadow_origin,
                shadow_right,
                shadow_up,
                shadow_fwd,
                shadow_scale,
                width,
                height,
                color_by,
                auto_range,
                floor,
                shadows,
                n_objects,
                n_palette,
                channels,
                pad
            ]
        ),
        layout!(
            RenderObject,
            "RenderObject",
            [shape, rot, pivot, lo, hi, plane_p, plane_n, plane]
        ),
        layout!(
            SharedCtx,
            "SharedCtx",
            [
                mask,
                counts,
                chunk,
                shared_local,
                buf,
                holders,
                dims,
                d,
                cap,
                pad
            ]
        ),
        layout!(PeerCtx, "PeerCtx", [mask, buf, n, me]),
        layout!(
            PushCtx,
            "PushCtx",
            [inbox, arrivals, calls, done, timeout_ns, n, me]
        ),
        layout!(RedoWorlds, "RedoWorlds", [count, lo, hi]),
        layout!(
            SpinBarrier,
            "SpinBarrier",
            [count, calls, timeout_ns, n, pad]
        ),
        layout!(
            RmapCtx,
            "RmapCtx",
            [contrib, counts, entries, node_cap, replicas, slots, pad]
        ),
        layout!(
            SortCtx,
            "SortCtx",
            [
                contrib,
                keys,
                vals,
                tile_counts,
                scan_sums,
                seg_start,
                seg_end,
                n_items,
                n_tiles,
                node_cap,
                pad
            ]
        ),
    ]
}

/// `FLUID` for `fluid`.
fn upper(name: &str) -> String {
    name.to_ascii_uppercase()
}

/// `FluidParams` for `fluid`.
fn params_struct(name: &str) -> String {
    name.split('_')
        .map(|w| {
            let mut c = w.chars();
            c.next()
                .map(|f| f.to_ascii_uppercase().to_string() + c.as_str())
                .unwrap_or_default()
        })
        .collect::<String>()
        + "Params"
}

/// `contract.cuh`: the shared constants as preprocessor definitions.
pub fn prelude() -> String {
    let mut s = String::from(
        "// Generated by crates/rtmpm-cuda/src/contract/headers.rs (the host/device contract): do not edit.\n#pragma once\n",
    );
    let mut def = |name: &str, v: String| {
        let _ = writeln!(s, "#define {name} {v}");
    };
    for (n, v) in [
        ("FILL_WORDS", FILL_WORDS),
        ("FT_START", FT_START),
        ("FT_COUNT", FT_COUNT),
        ("FT_V0", FT_V0),
        ("FT_W", FT_W),
        ("FT_CENTRE", FT_CENTRE),
        ("FT_NCONST", FT_NCONST),
        ("FT_CONST", FT_CONST),
        ("SAMPLE_WORDS", SAMPLE_WORDS),
        ("SP_ORIGIN", SP_ORIGIN),
        ("SP_H", SP_H),
        ("SP_FIRST", SP_FIRST),
        ("SP_NX", SP_NX),
        ("SP_NY", SP_NY),
        ("SP_JITTER", SP_JITTER),
        ("SP_STATE", SP_STATE),
        ("SP_INC", SP_INC),
        ("SP_SHAPE", SP_SHAPE),
        ("SP_PARAMS", SP_PARAMS),
        ("SP_DIMS", SP_DIMS),
        ("SAMPLE_LATTICE", SAMPLE_LATTICE as usize),
        ("SAMPLE_RANDOM", SAMPLE_RANDOM as usize),
        ("SAMPLE_TRIES_PER_ROW", SAMPLE_TRIES_PER_ROW as usize),
        ("SP_KIND", SP_KIND),
        ("SP_HI", SP_HI),
        ("SP_TRIES", SP_TRIES),
        ("CTL_NEED_REBUILD", CTL_NEED_REBUILD),
        ("CTL_GBLOCKS", CTL_GBLOCKS),
        ("CTL_PBLOCKS", CTL_PBLOCKS),
        ("CTL_ERROR", CTL_ERROR),
        ("CTL_BAD_INDEX", CTL_BAD_INDEX),
        ("CTL_BAD_REASON", CTL_BAD_REASON),
        ("CTL_MAX_SPEED", CTL_MAX_SPEED),
        ("CTL_REBUILDS", CTL_REBUILDS),
        ("CTL_WARPS", CTL_WARPS),
        ("CTL_EXTRA", CTL_EXTRA),
        ("CTL_PREV_GBLOCKS", CTL_PREV_GBLOCKS),
        ("CTL_REBUILT_NOW", CTL_REBUILT_NOW),
        ("CTL_SHARED", CTL_SHARED),
        ("CTL_SHARED_CAP", CTL_SHARED_CAP),
        ("CTL_BARRIER_COUNT", CTL_BARRIER_COUNT),
        ("CTL_BARRIER_GEN", CTL_BARRIER_GEN),
        ("CTL_P2G_PENDING", CTL_P2G_PENDING),
        ("CTL_WORDS", CTL_WORDS),
        ("RTMPM_MAX_COLLIDERS", MAX_COLLIDERS),
        ("RTMPM_MAX_MATERIALS", MAX_MATERIALS),
        ("RTMPM_MAX_BODIES", MAX_BODIES),
        ("REDO_RANGES", REDO_RANGES),
        ("PUT_GBLOCKS_PER_WARP", PUT_GBLOCKS_PER_WARP),
        ("REDO_ENTRIES_PER_WARP", REDO_ENTRIES_PER_WARP),
        ("BODY_EXCHANGE_SLOTS", BODY_EXCHANGE_SLOTS),
        ("MATERIAL_PARAMS", MATERIAL_PARAMS),
        ("SB_MAX_GPUS", MAX_PEER_GPUS),
        ("RENDER_SHADOW_RES", RENDER_SHADOW_RES),
        ("RENDER_BINS", RENDER_BINS),
        ("RENDER_MAX_OBJECTS", RENDER_MAX_OBJECTS),
        ("RS_MIN", RS_MIN),
        ("RS_MAX", RS_MAX),
        ("RS_LO", RS_LO),
        ("RS_HI", RS_HI),
        ("RS_PICK", RS_PICK),
        ("RS_COARSE", RS_COARSE),
        ("RS_FINE", RS_FINE),
        ("RS_WORDS", RS_WORDS),
    ] {
        def(n, v.to_string());
    }
    for (n, v) in [
        ("ERR_HASH", ERR_HASH),
        ("ERR_GBLOCKS", ERR_GBLOCKS),
        ("ERR_PBLOCKS", ERR_PBLOCKS),
        ("ERR_WARPS", ERR_WARPS),
        ("ERR_P2G_MAP", ERR_P2G_MAP),
        ("ERR_SHARED", ERR_SHARED),
        ("ERR_BARRIER", ERR_BARRIER),
        ("RENDER_OBJECT_ID", RENDER_OBJECT_ID),
    ] {
        def(n, format!("{v}u"));
    }
    for (n, c) in [
        ("COND_STICKY", Condition::Sticky),
        ("COND_SLIP", Condition::Slip),
        ("COND_SEPARATE", Condition::Separate),
    ] {
        def(n, format!("{}u", condition(c)));
    }
    for (n, t) in [
        ("TRANSFER_MLS", Transfer::Mls),
        ("TRANSFER_GIMP", Transfer::Gimp),
        ("TRANSFER_LINEAR", Transfer::MpmLinear),
        ("TRANSFER_CK", Transfer::CkMpm),
    ] {
        def(n, format!("{}u", t.code()));
    }
    for c in rtmpm_scene::ColorBy::ALL {
        let name = format!("RENDER_COLOR_{}", c.name().to_ascii_uppercase());
        def(&name, format!("{}u", color_code(c)));
    }
    def("UPDATE_USL", format!("{}u", update(Update::Usl)));
    def("UPDATE_MUSL", format!("{}u", update(Update::Musl)));
    s.push_str(&StateLayout::prelude());
    s
}

/// `geometry/registry.cuh`: every shape of `rtmpm_geometry::Shape::ALL` with its kind code
/// (`SHAPE_<NAME>`, [`rtmpm_geometry::Shape::code`]), the kernel file of each shape with a
/// device twin (`geometry/<name>.cuh`), and the three dispatch functions of the kernels (a plain
/// switch over the kind, for an arithmetic `A`: `geometry/geometry.cuh`).
pub fn shape_registry() -> String {
    use rtmpm_geometry::Shape;
    let mut s = String::from(
        "// Generated by crates/rtmpm-cuda/src/contract/headers.rs from rtmpm_geometry::Shape::ALL: do not\n\
         // edit. Each shape's device functions are in geometry/<name>.cuh.\n#pragma once\n\
         #include \"geometry.cuh\"\n\n",
    );
    for (code, sh) in Shape::ALL.iter().enumerate() {
        let _ = writeln!(s, "#define SHAPE_{} {code}u", upper(sh.name));
    }
    s.push('\n');
    let device: Vec<&str> = Shape::ALL
        .iter()
        .filter(|sh| sh.device)
        .map(|sh| sh.name)
        .collect();
    for name in &device {
        let _ = writeln!(s, "#include \"{name}.cuh\"");
    }
    let dispatch = |s: &mut String, doc: &str, head: &str, call: &str, fallback: &str| {
        let _ = write!(
            s,
            "\n// {doc}\ntemplate <class A, class T = typename A::T>\nGEO_FN {head} {{\n    switch (kind) {{\n"
        );
        for name in &device {
            let _ = writeln!(
                s,
                "    case SHAPE_{}: {};",
                upper(name),
                call.replace("NAME", name)
            );
        }
        let _ = writeln!(s, "    }}\n    {fallback}\n}}");
    };
    dispatch(
        &mut s,
        "Signed distance of shape `kind` (a shape without a device twin: far outside).",
        "T shape_distance_of(unsigned kind, const GeoShape& g, const T* x)",
        "return NAME_distance<A>(g, x)",
        "return A::of(GEO_FAR);",
    );
    dispatch(
        &mut s,
        "Outward unit normal of shape `kind` into n.",
        "void shape_normal_of(unsigned kind, const GeoShape& g, const T* x, T* n)",
        "NAME_normal<A>(g, x, n); return",
        "n[0] = A::of(0.0f); n[1] = A::of(1.0f); n[2] = A::of(0.0f);",
    );
    dispatch(
        &mut s,
        "True when a body or an emitter of shape `kind` holds x (Shape::contains).",
        "bool shape_contains_of(unsigned kind, const GeoShape& g, const T* x)",
        "return NAME_contains<A>(g, x)",
        "return false;",
    );
    s
}

/// `material/registry.cuh`: every model of `rtmpm_physics::material::Model::ALL` with its kind code,
/// its parameter struct (the fields of `GPU_PARAMS`, in order), its kernel file, and the two
/// dispatch functions of the kernels (a plain switch over the kind).
pub fn material_registry() -> String {
    let mut s = String::from(
        "// Generated by crates/rtmpm-cuda/src/contract/headers.rs from rtmpm_physics::material::Model::ALL: do not\n\
         // edit. Each model's device functions are in material/<name>.cuh.\n#pragma once\n\n",
    );
    for (code, m) in Model::ALL.iter().enumerate() {
        let _ = writeln!(s, "#define MATERIAL_{} {code}u", upper(m.name));
    }
    s.push_str(
        "\n// The models a program is compiled for: bit k of RTMPM_MATERIAL_MASK for kind k (the backend\n\
         // passes its scene's, so a kernel holds only the models it can meet; default: all).\n\
         #ifndef RTMPM_MATERIAL_MASK\n#define RTMPM_MATERIAL_MASK 0xffffffffu\n#endif\n\
         #define RTMPM_HAS_MATERIAL(kind) ((RTMPM_MATERIAL_MASK >> (kind)) & 1u)\n\n",
    );
    for m in Model::ALL {
        let _ = writeln!(s, "// {}: {}", m.name, m.summary);
        let _ = write!(s, "struct {} {{", params_struct(m.name));
        for p in m.gpu_params {
            let _ = write!(s, " real {p};");
        }
        s.push_str(" };\n");
        let fields: Vec<String> = (0..m.gpu_params.len())
            .map(|i| format!("m.p[{i}]"))
            .collect();
        let _ = writeln!(
            s,
            "__device__ __forceinline__ {0} {1}_params(const MaterialGpu& m) {{ return {0}{{{2}}}; }}",
            params_struct(m.name),
            m.name,
            fields.join(", ")
        );
    }
    s.push('\n');
    for m in Model::ALL {
        let _ = writeln!(s, "#include \"{}.cuh\"", m.name);
    }
    s.push_str(
        "\n// Kirchhoff stress tau = P F^T of material m (c: the APIC affine matrix, for viscous models).\n\
         __device__ __forceinline__ mat3 material_kirchhoff(const MaterialGpu& m, const mat3& f, real plastic, const mat3& c) {\n    switch (m.kind) {\n",
    );
    for m in Model::ALL {
        let _ = writeln!(
            s,
            "    case MATERIAL_{}: if (RTMPM_HAS_MATERIAL(MATERIAL_{0})) return {1}_kirchhoff({1}_params(m), f, plastic, c); break;",
            upper(m.name),
            m.name
        );
    }
    s.push_str(
        "    }\n    return mat3_zero();\n}\n\n\
         // Plastic return mapping of the trial elastic F of material m after a step dt; updates *plastic.\n\
         __device__ __forceinline__ mat3 material_project(const MaterialGpu& m, const mat3& f_trial, real* plastic, real dt) {\n    switch (m.kind) {\n",
    );
    for m in Model::ALL {
        let _ = writeln!(
            s,
            "    case MATERIAL_{}: if (RTMPM_HAS_MATERIAL(MATERIAL_{0})) return {1}_project({1}_params(m), f_trial, plastic, dt); break;",
            upper(m.name),
            m.name
        );
    }
    s.push_str("    }\n    return f_trial;\n}\n");
    s
}

/// The end of the program: a `static_assert` of the size and of every field offset of every
/// struct shared with the host, in the precision `f64` or f32.
pub fn layout_asserts(f64: bool) -> String {
    let all = if f64 {
        layouts::<f64>()
    } else {
        layouts::<f32>()
    };
    let mut s = String::from(
        "\n#line 1 \"layout checks (src/contract/layout.rs)\"\n// Generated by crates/rtmpm-cuda/src/contract/headers.rs: the layouts the host uses.\n\
         #ifndef offsetof\n#ifdef __CUDACC_RTC__\n#define offsetof(type, field) __INTADDR__(&(((type*)0)->field))\n#else\n\
         #define offsetof(type, field) __builtin_offsetof(type, field)\n#endif\n#endif\n",
    );
    for l in all {
        let _ = writeln!(
            s,
            "static_assert(sizeof({0}) == {1}, \"{0}: the host's struct (src/contract/layout.rs) has {1} bytes\");",
            l.name, l.size
        );
        for (f, off) in l.fields {
            let _ = writeln!(
                s,
                "static_assert(offsetof({0}, {f}) == {off}, \"{0}.{f}: the host (src/contract/layout.rs) has it at byte {off}\");",
                l.name
            );
        }
    }
    s
}

/// The materials of a scene in the kernels' precision.
pub fn materials<R: GpuReal>(models: &[(u32, Vec<R>)]) -> Result<Vec<MaterialGpu<R>>, String> {
    models
        .iter()
        .map(|(kind, params)| {
            if params.len() > MATERIAL_PARAMS {
                return Err(format!(
                    "a material has {} GPU parameters, at most {MATERIAL_PARAMS}",
                    params.len()
                ));
            }
            let mut p = [R::default(); MATERIAL_PARAMS];
            p[..params.len()].copy_from_slice(params);
            Ok(MaterialGpu {
                p,
                kind: *kind,
                pad: 0,
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_registry_fits_the_parameter_table_and_names_every_model() {
        for m in Model::ALL {
            assert!(m.gpu_params.len() <= MATERIAL_PARAMS, "{}", m.name);
        }
        let r = material_registry();
        assert!(r.contains(
            "struct FluidParams { real bulk_modulus; real tait; real gamma; real viscosity; };"
        ));
        assert!(r.contains("case MATERIAL_VON_MISES: if (RTMPM_HAS_MATERIAL(MATERIAL_VON_MISES)) return von_mises_kirchhoff(von_mises_params(m), f, plastic, c); break;"));
        assert!(r.contains("VonMisesParams von_mises_params(const MaterialGpu& m) { return VonMisesParams{m.p[0], m.p[1], m.p[2], m.p[3]}; }"));
        assert!(r.contains("#include \"drucker_prager.cuh\""));
    }

    #[test]
    fn layout_asserts_name_every_field() {
        let a = layout_asserts(false);
        assert!(a.contains("static_assert(offsetof(Ctx, state) == 0,"));
        assert!(a.contains("static_assert(offsetof(Scalars, dx) == 12,"));
        let b = layout_asserts(true);
        assert!(b.contains("static_assert(offsetof(Scalars, dx) == 24,"));
        assert!(b.contains("static_assert(sizeof(MaterialGpu) == 72,"));
        // Every field of Ctx is listed: the offsets end at its size.
        let ctx = &layouts::<f32>()[0];
        assert_eq!(ctx.fields.last().map(|f| f.1 + 4), Some(ctx.size));
    }

    #[test]
    fn materials_are_padded_with_zeros_and_refuse_too_many_parameters() {
        let m = materials::<f64>(&[(3, vec![1.0, 2.0])]).unwrap();
        assert_eq!(m[0].kind, 3);
        assert_eq!(&m[0].p[..3], &[1.0, 2.0, 0.0]);
        assert!(materials::<f32>(&[(0, vec![0.0; MATERIAL_PARAMS + 1])]).is_err());
    }
}

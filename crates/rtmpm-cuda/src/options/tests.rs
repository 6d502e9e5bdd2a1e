//! Tests of the CUDA options: parsing every switch, the errors for bad values, the defaults and
//! their resolution per kernel set.

use super::*;

#[test]
fn options_parse() {
    let o: CudaOptions = "free_zone=off, p2g=shared, gblocks=10".parse().unwrap();
    assert!(!o.free_zone && o.p2g == P2gMode::Shared && o.gblock_capacity == Some(10));
    assert_eq!(
        "bogus=1".parse::<CudaOptions>().unwrap_err(),
        "unknown CUDA option `bogus`"
    );
    let o: CudaOptions = "p2g=reverse_map,rmap_replicas=1,rmap_slots=40"
        .parse()
        .unwrap();
    assert!(o.p2g == P2gMode::ReverseMap && o.rmap_replicas == 1 && o.rmap_slots == Some(40));
    let o: CudaOptions = "p2g=sort".parse().unwrap();
    assert_eq!(o.p2g, P2gMode::Sort);
    assert!("p2g=gather".parse::<CudaOptions>().is_err());
    assert_eq!(CudaOptions::default().ck_p2g, CkP2g::Fused);
    assert!(CudaOptions::default().batch_sums_at_read);
    let o: CudaOptions = "body_sums=step".parse().unwrap();
    assert!(!o.batch_sums_at_read);
    assert_eq!(CudaOptions::default().batch_poses, BodyPoses::Deferred);
    let o: CudaOptions = "body_poses=eager".parse().unwrap();
    assert!(o.batch_poses == BodyPoses::Eager && o.batch_sums_at_read);
    let o: CudaOptions = "body_poses=deferred_serial".parse().unwrap();
    assert_eq!(o.batch_poses, BodyPoses::DeferredSerial);
    assert!(CudaOptions::default().batch_body_turns);
    let o: CudaOptions = "body_upload=serial".parse().unwrap();
    assert!(!o.batch_body_turns && o.batch_sums_at_read);
    assert!(
        "body_upload=turns"
            .parse::<CudaOptions>()
            .unwrap()
            .batch_body_turns
    );
    assert!("body_upload=both".parse::<CudaOptions>().is_err());
    let e = "body_sums=never".parse::<CudaOptions>().unwrap_err();
    assert!(e.contains("expected read or step"), "{e}");
    let o: CudaOptions = "ck_p2g=warp".parse().unwrap();
    assert_eq!((o.ck_p2g, o.p2g), (CkP2g::Warp, P2gMode::Warp));
    assert_eq!(o.ck_p2g.name(), "warp");
    assert_eq!(
        "ck_p2g=direct".parse::<CudaOptions>().unwrap().ck_p2g,
        CkP2g::Direct
    );
    let e = "ck_p2g=shared".parse::<CudaOptions>().unwrap_err();
    assert_eq!(e, "`ck_p2g=shared`: expected direct, warp or fused");
    assert_eq!(
        "ck_p2g=fused".parse::<CudaOptions>().unwrap().ck_p2g,
        CkP2g::Fused
    );
    let e = "rebuild=maybe".parse::<CudaOptions>().unwrap_err();
    assert_eq!(e, "`rebuild=maybe`: expected fused or kernels");
    assert_eq!(
        choice("k=x", "x", &[("a", 1), ("b", 2), ("c", 3)]).unwrap_err(),
        "`k=x`: expected a, b or c"
    );
    assert!("rmap_replicas=0".parse::<CudaOptions>().is_err());
    let o: CudaOptions = "transport=p2p,barrier=events".parse().unwrap();
    assert_eq!(o.transport, Some(Transport::P2p));
    assert_eq!(o.barrier, Some(BarrierKind::Events));
    assert!("transport=mpi".parse::<CudaOptions>().is_err());
    assert!("barrier=sleep".parse::<CudaOptions>().is_err());
    assert_eq!(CudaOptions::default().exchange, None);
    assert_eq!(CudaOptions::default().overlap, None);
    assert_eq!(
        "overlap=off".parse::<CudaOptions>().unwrap().overlap,
        Some(false)
    );
    for (v, m) in [
        ("kernels", ExchangeMode::Kernels),
        ("fused", ExchangeMode::Fused),
        ("push", ExchangeMode::Push),
        ("push_update", ExchangeMode::PushUpdate),
        ("list_push_update", ExchangeMode::ListPushUpdate),
    ] {
        let o: CudaOptions = format!("exchange={v}").parse().unwrap();
        assert_eq!(o.exchange, Some(m));
    }
    assert_eq!(
        "exchange=pull".parse::<CudaOptions>().unwrap_err(),
        "`exchange=pull`: expected kernels, fused, push, push_update or list_push_update"
    );
    assert_eq!(CudaOptions::default().partition, PartitionKind::Slabs);
    assert_eq!(
        "partition=boxes".parse::<CudaOptions>().unwrap().partition,
        PartitionKind::Boxes
    );
    assert_eq!(
        "partition=cubes".parse::<CudaOptions>().unwrap_err(),
        "`partition=cubes`: expected slabs or boxes"
    );
    assert!(CudaOptions::default().fused_rebuild);
    assert!(
        !"rebuild=kernels"
            .parse::<CudaOptions>()
            .unwrap()
            .fused_rebuild
    );
    assert!("rebuild=maybe".parse::<CudaOptions>().is_err());
    assert!(CudaOptions::default().g2p2g);
    assert!(!"g2p2g=off".parse::<CudaOptions>().unwrap().g2p2g);
    assert!(!CudaOptions::default().specialize);
    assert!("specialize=on".parse::<CudaOptions>().unwrap().specialize);
    assert_eq!(CudaOptions::default().sort_scratch_fields, 4);
    let o: CudaOptions = "sort_fields=29".parse().unwrap();
    assert_eq!(o.sort_scratch_fields, crate::contract::MAX_FIELDS);
    assert!(CudaOptions::default().fluid_state && !CudaOptions::default().compact_state);
    let o: CudaOptions = "fluid_state=off,state=compact".parse().unwrap();
    assert!(!o.fluid_state && o.compact_state);
    assert!("state=f16".parse::<CudaOptions>().is_err());
    assert!("sort_fields=0".parse::<CudaOptions>().is_err());
    assert!("sort_fields=30".parse::<CudaOptions>().is_err());
    assert!(CudaOptions::default().device_fill);
    assert!(!"fill=host".parse::<CudaOptions>().unwrap().device_fill);
    assert!("fill=device".parse::<CudaOptions>().unwrap().device_fill);
    assert!(CudaOptions::default().device_sample);
    assert!(!"sample=host".parse::<CudaOptions>().unwrap().device_sample);
    assert!("sample=bad".parse::<CudaOptions>().is_err());
    assert!("fill=gpu".parse::<CudaOptions>().is_err());
    assert_eq!(CudaOptions::default().devices, None);
    let o: CudaOptions = "devices=0:0,transport=p2p".parse().unwrap();
    assert_eq!(o.devices, Some(vec![0, 0]));
    assert_eq!(o.transport, Some(Transport::P2p));
    assert_eq!(
        "devices=3".parse::<CudaOptions>().unwrap().devices,
        Some(vec![3])
    );
    let e = "devices=0:x".parse::<CudaOptions>().unwrap_err();
    assert!(e.contains("ordinals separated by `:`"), "{e}");
    assert!("devices=".parse::<CudaOptions>().is_err());
    let d = CudaOptions::default();
    assert_eq!((d.ck_min_blocks, d.ck_resident_grid), (None, None));
    let o: CudaOptions = "ck_bound=5,ck_grid=resident".parse().unwrap();
    assert_eq!((o.ck_min_blocks, o.ck_resident_grid), (Some(5), Some(true)));
    assert!("ck_bound=17".parse::<CudaOptions>().is_err());
    assert!("ck_grid=big".parse::<CudaOptions>().is_err());
    assert!(CudaOptions::default().stencil_pairs);
    assert!(
        !"addressing=blocks"
            .parse::<CudaOptions>()
            .unwrap()
            .stencil_pairs
    );
    assert!(
        "addressing=pairs"
            .parse::<CudaOptions>()
            .unwrap()
            .stencil_pairs
    );
    assert_eq!(
        "addressing=nodes".parse::<CudaOptions>().unwrap_err(),
        "`addressing=nodes`: expected pairs or blocks"
    );
    let d = CudaOptions::default().fused;
    assert_eq!(d, FusedSwitches::default());
    assert_eq!(d.defaults, DEFAULT_FUSED_DEFAULTS);
    assert_eq!(
        (d.row_unroll, d.lean_lanes, d.seg_clamp, d.zero_terms),
        (None, None, None, None)
    );
    assert_eq!((d.flat_checks, d.wide_state_index), (None, None));
    let sets = [KernelSet::Fluid, KernelSet::General];
    let o: CudaOptions =
        "lean_lanes=on,seg_clamp=on,zero_terms=skip,flat_checks=on,state_index=wide"
            .parse()
            .unwrap();
    let all_cuts = crate::KernelCuts {
        lean_lanes: true,
        seg_clamp: true,
        zero_terms: true,
        flat_checks: true,
    };
    for set in sets {
        let c = o.fused.resolve(set);
        assert_eq!(c.cuts, all_cuts, "{set:?}");
        assert!(c.wide_state_index, "{set:?}");
        assert_eq!(c.cuts.defines().len(), 4);
        // Explicit values for every switch: the same code whatever fused_defaults says.
        for fd in ["off", "auto"] {
            let o2: CudaOptions = format!(
                "fused_defaults={fd},row_unroll=off,lean_lanes=off,seg_clamp=off,\
                 zero_terms=keep,flat_checks=off,state_index=auto"
            )
            .parse()
            .unwrap();
            assert_eq!(o2.fused.resolve(set), FusedCode::default(), "{fd} {set:?}");
        }
    }
    assert_eq!(
        "zero_terms=on".parse::<CudaOptions>().unwrap_err(),
        "`zero_terms=on`: expected skip or keep"
    );
    assert_eq!(
        "state_index=64".parse::<CudaOptions>().unwrap_err(),
        "`state_index=64`: expected wide or auto"
    );
    for (v, r, d) in [
        ("off", RowUnroll::Off, 0),
        ("planes", RowUnroll::Planes, 2),
        ("all", RowUnroll::All, 1),
    ] {
        let o: CudaOptions = format!("row_unroll={v}").parse().unwrap();
        assert_eq!(o.fused.row_unroll, Some(r));
        for set in sets {
            let u = o.fused.resolve(set).row_unroll;
            assert_eq!((u, u.define()), (r, d));
        }
    }
    assert_eq!(
        "row_unroll=rows".parse::<CudaOptions>().unwrap_err(),
        "`row_unroll=rows`: expected off, planes or all"
    );
    assert!(!CudaOptions::default().pdl);
    assert!("pdl=on".parse::<CudaOptions>().unwrap().pdl);
    assert!(!"pdl=on,pdl=off".parse::<CudaOptions>().unwrap().pdl);
    assert_eq!(
        "pdl=auto".parse::<CudaOptions>().unwrap_err(),
        "`pdl=auto`: expected on/off"
    );
    assert!(CudaOptions::default().uniform_loop);
    assert!(
        !"uniform_loop=off"
            .parse::<CudaOptions>()
            .unwrap()
            .uniform_loop
    );
}

/// `fused_defaults`: `off` gives today's code to every kernel set; `auto` gives the fluid set
/// `row_unroll=planes` with `seg_clamp`, `zero_terms=skip`, `flat_checks` and the wide state
/// index and the general set today's code; a switch given explicitly overrides it in every
/// set, in whichever order the two are written; the default is [`DEFAULT_FUSED_DEFAULTS`].
#[test]
fn fused_defaults_resolve_per_kernel_set() {
    use rtmpm_physics::transfer::Transfer;
    assert_eq!(KernelSet::of(true, Transfer::Mls), KernelSet::Fluid);
    for t in [Transfer::CkMpm, Transfer::Gimp, Transfer::MpmLinear] {
        assert_eq!(KernelSet::of(true, t), KernelSet::General, "{t:?}");
    }
    assert_eq!(KernelSet::of(false, Transfer::Mls), KernelSet::General);
    let (fluid, general) = (KernelSet::Fluid, KernelSet::General);
    let off: CudaOptions = "fused_defaults=off".parse().unwrap();
    assert_eq!(off.fused.defaults, FusedDefaults::Off);
    assert_eq!(off.fused.resolve(fluid), FusedCode::default());
    assert_eq!(off.fused.resolve(general), FusedCode::default());
    let auto: CudaOptions = "fused_defaults=auto".parse().unwrap();
    assert_eq!(auto.fused.defaults.name(), "auto");
    let tuned = auto.fused.resolve(fluid);
    assert_eq!(tuned, FusedCode::FLUID_TUNED);
    assert_eq!(
        (tuned.row_unroll, tuned.cuts.defines().len()),
        (RowUnroll::Planes, 3)
    );
    assert!(tuned.wide_state_index && !tuned.cuts.lean_lanes);
    assert_eq!(auto.fused.resolve(general), FusedCode::default());
    // Last session's comparison, given explicitly: the same code in both sets, with or
    // without auto.
    let ab = "row_unroll=planes,seg_clamp=on,zero_terms=skip,flat_checks=on,state_index=wide";
    for o in [ab.to_string(), format!("fused_defaults=auto,{ab}")] {
        let o: CudaOptions = o.parse().unwrap();
        assert_eq!(o.fused.resolve(fluid), FusedCode::FLUID_TUNED, "{o:?}");
        assert_eq!(o.fused.resolve(general), FusedCode::FLUID_TUNED, "{o:?}");
    }
    // An explicit value beats auto in the fluid set, and applies to the general set too.
    for s in [
        "fused_defaults=auto,row_unroll=off,lean_lanes=on",
        "row_unroll=off,lean_lanes=on,fused_defaults=auto",
    ] {
        let o: CudaOptions = s.parse().unwrap();
        let f = o.fused.resolve(fluid);
        assert_eq!(f.row_unroll, RowUnroll::Off, "{s}");
        assert!(
            f.cuts.lean_lanes && f.cuts.seg_clamp && f.wide_state_index,
            "{s}"
        );
        let g = o.fused.resolve(general);
        assert_eq!(g.row_unroll, RowUnroll::Off, "{s}");
        assert!(
            g.cuts.lean_lanes && !g.cuts.seg_clamp && !g.wide_state_index,
            "{s}"
        );
    }
    // Every switch given: `all` is that code in every set.
    for set in [fluid, general] {
        for code in [FusedCode::default(), FusedCode::FLUID_TUNED] {
            assert_eq!(FusedSwitches::all(code).resolve(set), code);
        }
    }
    assert_eq!(
        "fused_defaults=on".parse::<CudaOptions>().unwrap_err(),
        "`fused_defaults=on`: expected off or auto"
    );
    // The default resolves as its value says.
    let d = CudaOptions::default().fused;
    let explicit: CudaOptions = format!("fused_defaults={}", DEFAULT_FUSED_DEFAULTS.name())
        .parse()
        .unwrap();
    for set in [fluid, general] {
        assert_eq!(d.resolve(set), explicit.fused.resolve(set));
    }
}

/// The experiments removed after they lost on an H200 (bench/RESULTS.md: the thread-block
/// clusters `cluster=`, the shared node halo `halo=` and the sorted warp list `warp_list=`)
/// are unknown options now, with the error every unknown option gets, whatever the value.
#[test]
fn removed_experiment_options_are_unknown() {
    for (item, key) in [
        ("cluster=2", "cluster"),
        ("cluster=off", "cluster"),
        ("halo=sync", "halo"),
        ("halo=async", "halo"),
        ("halo=off", "halo"),
        ("warp_list=sorted", "warp_list"),
        ("warp_list=arrival", "warp_list"),
    ] {
        assert_eq!(
            format!("free_zone=on,{item}")
                .parse::<CudaOptions>()
                .unwrap_err(),
            format!("unknown CUDA option `{key}`"),
            "{item}"
        );
    }
}

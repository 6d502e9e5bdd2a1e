#!/usr/bin/env bash
# The one GPU-run script: named suites, run on the device machine with the binaries that
# scripts/gpu/prepare.sh built here (carried in .device/). Full logs go to $OUT; a short
# summary (summary.txt) is printed last.
#
#   bash scripts/gpu/run.sh SUITE [SUITE...]
#
# Suites:
#   tests        GPU tests (TESTS="test_gpu ..." to choose; TEST_TIMEOUT seconds each, 500): kernels, P2G strategies, transfers, f64, the material check
#                (every model on the GPU against Rust), the CPU/GPU agreement on every example
#                scene, emitters and the keyframed paddle against the CPU (test_emitters), the CLI on the GPU
#   validate     the validation suite at full resolution on the GPU (`rtmpm validate`)
#   ck           CK-MPM on the GPU: test_agreement's cuda_agrees_with_cpu_with_ck_mpm (f32 and f64
#                against the CPU reference), then the four *_ck validation cases at full resolution, in
#                f32 and (vibrating_bar_ck) f64; then ms/step of the fluid dam 2M and the jelly 2M with
#                MLS-MPM (fused G2P2G, and g2p2g=off) and with CK-MPM (the same scene, [solver] transfer
#                = "ck-mpm") with each CK-MPM P2G kernel (ck_p2g=direct, ck_p2g=warp, the warp
#                reduction, ck_p2g=fused, G2P2G and the default); the agreement test with the default kernel
#                (CK_AGREEMENT="ck_p2g=direct;ck_p2g=warp;ck_p2g=fused" for all, about 3 min each)
#   ck_speed     the CK-MPM kernel variants only: the benchmarks of `ck` (about 3 min; CK_VARIANTS: the
#                --cuda-options of each CK-MPM line, default "ck_p2g=direct ck_p2g=warp ck_p2g=fused"),
#                then the agreement test with the new kernels only (about 3 min a variant;
#                RTMPM_CK_AGREEMENT from CK_AGREEMENT, default "ck_p2g=warp;ck_p2g=fused")
#   kernel_ab    the kernel switches of the CUDA options in one binary, interleaved REPS times (default
#                1; about 4 min, not timed: the first compile of each variant and 16 runs): MLS-MPM's fused step
#                as it is, and CK-MPM's kernels with an occupancy bound (ck_bound=N: N blocks of 128 a SM) and the
#                resident grid (ck_grid=resident) against ck_p2g=fused / ck_p2g=warp as they are, on
#                the fluid dam 2M and the jelly 2M; a table of ms/step last (KERNEL_AB_MLS,
#                KERNEL_AB_CK: the --cuda-options of each line, "-" for none)
#   kernel_agree the agreement tests with those switches: every example scene in f32 and f64 with each
#                --cuda-options of KERNEL_AGREE_MLS (RTMPM_AGREEMENT_OPTIONS; none by default, e.g.
#                KERNEL_AGREE_MLS="g2p2g=off"), then CK-MPM with ck_p2g=fused,ck_bound=5,ck_grid=resident
#                (RTMPM_CK_AGREEMENT; KERNEL_AGREE_CK to change, KERNEL_AGREE_CK=none to skip it)
#   validate_compact  the same with the compact particle state (`--particle-state compact`)
#   convergence  the convergence studies and the f64 validation cases
#   bench        the claymore scenes (fluid 2M, jelly 2M, snow 1.33M) and a fluid block; with
#                .device/rtmpm_base, A/B against that build, interleaved (REPS=2 by default);
#                BENCH_RUNS="bin|cuda-options ..." sets the runs (default "rtmpm_base| rtmpm|")
#   ablation     the switches of the principles of Fei, Huang & Gao on the claymore scenes (--cuda-options)
#   variants     A/B of compile-time defines: VARIANTS="label|binary|defines[|options] ..." (several
#                defines in one entry separated by commas), interleaved REPS times (default 1)
#   sanitize     compute-sanitizer (memcheck, then racecheck and synccheck) on short runs of the fused step: the
#                snow 1.33M (general G2P2G; a bench scene: bench needs a fixed dt) and a fluid block n = 64 (fluid G2P2G), 20 steps each, with
#                RTMPM_KERNEL_DEFINES as set by the caller (SANITIZE_TOOLS to choose the tools;
#                SANITIZE_OPTIONS: --cuda-options of the runs, e.g. g2p2g=off)
#   profile      Nsight Compute on the fused G2P2G kernel (one launch after 5): PROFILE_RUNS="label|binary|
#                defines|scene ..." (default: the fluid dam 2M); the bound (issue, stalls, L1/L2, atomics)
#   multi        several GPUs: agreement tests in every mode, 2 NCCL processes, scaling
#   multi_rigid  rigid bodies with one process per GPU (2 GPUs and NCCL; skipped with fewer), after one GPU run
#                twice (one_gpu_twice_agrees_with_itself_on_the_rigid_scenes): test_multi_gpu_rigid's
#                nccl_ranks_agree_with_one_gpu_on_the_rigid_scenes (two NCCL ranks in two threads, every
#                scenes/rigid/ scene 0.5 s at a fixed dt, a re-partition halfway, against one GPU; the ranks'
#                bodies equal bit for bit) and test_multi_gpu_cli's two_processes_agree_with_one_gpu_on_the_rigid_scenes
#                (`rtmpm run --rendezvous` in two processes against one GPU, bodies.csv and the last frame).
#                Both are also part of `multi`
#   multi4       the same on 4 GPUs: agreement at 2 and 4, strong and weak scaling at 1, 2, 4, 4 ranks
#   exchange     --cuda-options exchange=fused|push|push_update against the default (docs/multi-gpu.md, "The exchange's
#                launches"): test_multi_gpu_agreement's the_fused_and_pushed_exchanges_agree_with_one_gpu, then the weak
#                benchmark (4.2M a GPU) on 1 GPU and on 2 and 4 GPUs (those present) with exchange=kernels,
#                fused, push, push+overlap=off, push_update (the inbox summed in the grid update),
#                list_push_update (and the list made with the push) and overlap=off, REPS times
#                interleaved (default 2), then the strong 16.8M at 1, 2, 4 with kernels, push,
#                push+overlap=off, push_update, list_push_update (EXCHANGE_STRONG=0 skips it); at 4 GPUs
#                also partition=boxes (2 x 2 pieces) with push and list_push_update; each run's reduction
#                line in the summary (push_update's includes its grid update, list_push_update's also the
#                list). About 7 min on 4 GPUs
#   multi1       the multi-GPU code on ONE GPU: the test_multi_gpu_* binaries with two ranks on device 0
#                (RTMPM_MULTI_GPU_DEVICES=0,0, the CUDA option devices=0:0; transport=p2p with the events
#                barrier, the spin barrier and NCCL checked to be refused there): every example scene,
#                steering, the rigid scenes (scenes/rigid/*) and the bad-particle report against one GPU;
#                then `rtmpm run scenes/rigid/floating_box.toml` for 30 frames on 1 GPU and on 2 ranks of it
#                (last rows of both bodies.csv). About 2-4 min.
#   python       the Python package's tests on the GPU (wheel in .device/wheels; PY_K="view or render_gpu"
#                picks tests as pytest -k does)
#   cpu          the CPU backend on this machine's cores: `rtmpm bench --backend cpu --n 128` (524k
#                particles) at --threads 1 2 4 8 16 (CPU_THREADS, CPU_N, CPU_STEPS to change), a table of
#                M particle-steps/s and parallel efficiency; with .device/rtmpm_base, that build too;
#                Taichi's mpm3d (bench/taichi_mpm3d.py) on the same scene when python3 imports taichi
#   frames       frame writing: test_frames (streamed GPU frames byte-identical to the
#                whole-frame files), then `rtmpm bench --frame-write` on fluid 2M, 16.8M and the n = 584 block
#                (49.8M): copy-out GB/s, write MB/s, step time with a frame written in the background
#                (FRAME_DIR, default /tmp/frames: the files are removed after each timing)
#   read         the read of every particle onto the host (`read_particles`: pooled page-locked memory,
#                unpacked by every core) on the fluid dam 2M after a frame: ms and GB/s (test_frames
#                gpu_read_particles_time), then test_frames whole (its files are written from that read)
#   scale        big scenes under /usr/bin/time -v (SCALE_RUNS="scene|cuda-options ...", default
#                water 500M with the device fill, then the host fill): set-up, throughput, bytes a particle
#   rigid        dam break 2M with 10 floating crates vs 10 static ones, floating_box on CUDA
#   view         a live view on the GPU: the render stage's time at 1280x720 for the dam break 2M and the
#                snow 1.33M against the scene's compute per displayed frame (target: at most 10 %), the frame
#                time with a picture drawn every frame against none (.device/render_bench; pictures in
#                $OUT/logs.tgz); then `rtmpm view --serve` on both, measured by a client on this machine:
#                the step time with the view on against `rtmpm bench` over the same frames (2..N) of the
#                same scene, without a client, with one, and with one but no overlap of pictures and steps
#                (scripts/viewer/view_cost.sh; VIEW_FRAMES, default "fluid_dam_2m:40 snow_1m:400"), the
#                host's time per picture and the stream's fps. About 3 min. The GPU tests of the render
#                stage and of steering are in `tests` (TESTS="test_render test_steer")
#   view-soak    memory over a long stream: the snow 1.33M streamed to a client on this machine for
#                VIEW_SOAK_SECONDS (default 600; a device call lasts at most 600 s, so 540 fits one),
#                host and GPU memory of the server at the start, middle and end (every VIEW_SOAK_EVERY s);
#                the view's default (pictures overlapped with the steps), RTMPM_VIEW_OVERLAP=0 in the
#                environment for the loop without
#   batch        many worlds in the same kernels: test_batch_isolation (16 wedge worlds vs 16 separate runs,
#                refusals), test_batch_resets (a reset and a blown-up world beside others, puts),
#                test_batch_put_slots (the put over the put worlds' gblocks against the put of every slot),
#                test_batch_rewind (the device rewind point), test_batch_lockstep (the lockstep driver, a
#                checkpointed batch resumed against the uninterrupted one), then test_batch_benchmark
#                (1,024 sand beds of 9,408 particles: batched vs one scene of as many particles vs worlds
#                one after another)
#   long         the strong-scaling scene for 12 frames (0.24 s, past its 0.1 s duration) on one GPU, fused
#                and unfused, and at dt/2: does the 12-frame blow-up seen on 2 GPUs happen on one?
set -uo pipefail
export NCCL_NVLS_ENABLE=0 TORCH_SYMM_MEM_DISABLE_MULTICAST=1 NVSHMEM_DISABLE_NVLS=1
D=${D:-.device}
OUT=${OUT:-/tmp/out}
mkdir -p "$OUT"
S="$OUT/summary.txt"
say() { echo "$*" | tee -a "$S"; }
say "$(nvidia-smi --query-gpu=name,driver_version --format=csv,noheader | head -1) x$(nvidia-smi -L | wc -l); commit $(cat $D/COMMIT 2>/dev/null); base $(cat $D/BASE_COMMIT 2>/dev/null || echo none); $(date -u +%FT%TZ)"
# The test binaries find the repository through the path they were built in (prepare.sh notes it).
B=$(cat "$D/BUILD_DIR" 2>/dev/null || true)
if [ -n "$B" ] && [ ! -e "$B" ]; then mkdir -p "$(dirname "$B")" && ln -sfn "$PWD" "$B"; fi
mkdir -p target/release && cp "$D/rtmpm" target/release/rtmpm

# test binary, args...: run it, one summary line with its result and failures.
t() {
  local name=$1; shift
  [ -x "$D/$name" ] || { say "$name: missing"; return; }
  timeout "${TEST_TIMEOUT:-500}" "$D/$name" --include-ignored --test-threads 1 "$@" > "$OUT/$name.log" 2>&1
  say "$name rc=$?: $(grep -E '^test result' "$OUT/$name.log" | tail -1)"
  grep -E "FAILED|panicked" "$OUT/$name.log" | head -8 | tee -a "$S"
}

# The test binaries of several GPUs (crates/rtmpm-cuda/tests/multi_gpu_*.rs) and of a GPU batch's
# worlds against their separate runs (tests/batch_*.rs but the colliders' and the rigid bodies').
MULTI_GPU_TESTS="test_multi_gpu_agreement test_multi_gpu_errors test_multi_gpu_rigid"
BATCH_TESTS="test_batch_isolation test_batch_resets test_batch_put_slots test_batch_rewind test_batch_lockstep"

# label, binary, bench args...: one summary line with ms/step and the stage times.
b() {
  local label=$1 bin=$2; shift 2
  local r; r=$(timeout 200 "$D/$bin" bench --backend cuda "$@" 2>&1)
  echo "== $label ($bin): $*" >> "$OUT/bench.log"; echo "$r" >> "$OUT/bench.log"
  local ms; ms=$(echo "$r" | grep -oE '\(([0-9.]+) ms/step\)' | head -1 | tr -d '()' | cut -d' ' -f1)
  local tp; tp=$(echo "$r" | grep -m1 "throughput" | sed -E 's/.*throughput +//; s/ \(.*//')
  local k; k=$(echo "$r" | grep -E '^\s+(rebuild|p2g|grid_update|musl_remap|g2p|g2p2g) ' | awk '{printf "%s=%s ", $1, $2}')
  B_MS=${ms:-?}
  local e; e=$(echo "$r" | grep -iE '^error' | head -1)
  printf '%-30s %-11s %9s ms/step %-22s %s%s\n' "$label" "$bin" "$ms" "$tp" "$k" "$e" | tee -a "$S"
}

CLAYMORE="fluid_dam_2m:10 jelly_drop_2m:5 snow_1m:20"

# The fluid dam 2M and the jelly 2M with MLS-MPM (fused G2P2G, and g2p2g=off) and with CK-MPM (the
# same scene, [solver] transfer = "ck-mpm") with each of its P2G kernels (CK_VARIANTS).
ck_bench() {
  for sc in fluid_dam_2m jelly_drop_2m; do
    cp "bench/$sc.toml" "$OUT/${sc}_ck.toml"
    printf '\n[solver]\ntransfer = "ck-mpm"\n' >> "$OUT/${sc}_ck.toml"
    b "$sc MLS-MPM" rtmpm --scene "bench/$sc.toml" --frames 5
    b "$sc MLS-MPM g2p2g=off" rtmpm --scene "bench/$sc.toml" --frames 5 --cuda-options g2p2g=off
    for v in ${CK_VARIANTS:-ck_p2g=direct ck_p2g=warp ck_p2g=fused}; do
      b "$sc CK-MPM $v" rtmpm --scene "$OUT/${sc}_ck.toml" --frames 5 --cuda-options "$v"
    done
  done
}

# The kernel switches of the CUDA options on the fluid dam 2M and the jelly 2M (suite kernel_ab):
# MLS-MPM lines on the scenes as they are, CK-MPM lines on the same scenes with [solver] transfer =
# "ck-mpm"; one row per line and scene, then a table of ms/step (one column per repetition).
kernel_ab() {
  local mls=${KERNEL_AB_MLS:-"-"}
  local ck=${KERNEL_AB_CK:-"ck_p2g=fused ck_p2g=fused,ck_grid=resident ck_p2g=fused,ck_bound=5 ck_p2g=fused,ck_bound=5,ck_grid=resident ck_p2g=fused,ck_bound=6,ck_grid=resident ck_p2g=warp ck_p2g=warp,ck_bound=5"}
  local table="$OUT/kernel_ab_table.txt" sc v o label
  : > "$table"
  for sc in fluid_dam_2m jelly_drop_2m; do
    cp "bench/$sc.toml" "$OUT/${sc}_ck.toml"
    printf '\n[solver]\ntransfer = "ck-mpm"\n' >> "$OUT/${sc}_ck.toml"
  done
  for rep in $(seq 1 "${REPS:-1}"); do
    for sc in fluid_dam_2m jelly_drop_2m; do
      for v in $mls; do
        o=${v#-}; label="MLS ${o:-default}"
        b "$sc $label" rtmpm --scene "bench/$sc.toml" --frames 5 ${o:+--cuda-options "$o"}
        echo "$sc|$label|$B_MS" >> "$table"
      done
      for v in $ck; do
        o=${v#-}; label="CK ${o:-default}"
        b "$sc $label" rtmpm --scene "$OUT/${sc}_ck.toml" --frames 5 ${o:+--cuda-options "$o"}
        echo "$sc|$label|$B_MS" >> "$table"
      done
    done
  done
  say "ms/step (whole run, graph replay; one figure per repetition):"
  python3 - "$table" <<'PY' | tee -a "$S"
import sys
rows, order = {}, []
for line in open(sys.argv[1]):
    sc, label, ms = line.rstrip("\n").split("|")
    if label not in rows:
        rows[label] = {}
        order.append(label)
    rows[label].setdefault(sc, []).append(ms)
print(f"| {'variant':45} | {'fluid dam 2M':18} | {'jelly drop 2M':18} |")
print(f"| {'-' * 45} | {'-' * 18} | {'-' * 18} |")
for label in order:
    r = rows[label]
    cell = lambda sc: ", ".join(r.get(sc, ["-"]))
    print(f"| {label:45} | {cell('fluid_dam_2m'):18} | {cell('jelly_drop_2m'):18} |")
PY
}

for suite in "$@"; do
  say "== $suite"
  case "$suite" in
    tests)
      mkdir -p "$OUT/test_pictures"
      for x in ${TESTS:-test_gpu test_fill test_sort_scratch test_state_layout test_materials test_agreement test_emitters test_rigid test_render test_steer test_cli test_render_cli}; do
        RTMPM_TEST_OUT="$OUT/test_pictures" t "$x"
      done
      grep -hE "mean \|diff\||turned by|gpu \(|particles in the ball|mean velocity|vs cpu" "$OUT"/test_render.log "$OUT"/test_steer.log 2>/dev/null | tee -a "$S"
      ;;
    validate)
      timeout 500 "$D/rtmpm" validate --backend cuda --out "$OUT/validation" > "$OUT/validate.log" 2>&1
      say "validate --backend cuda rc=$?"
      grep -E "PASS|FAIL|passed" "$OUT/validate.log" | sed -E 's/ +/ /g' | tee -a "$S"
      ;;
    ck)
      RTMPM_CK_AGREEMENT="${CK_AGREEMENT:-ck_p2g=fused}" t test_agreement cuda_agrees_with_cpu_with_ck_mpm --nocapture
      grep -E "ck-mpm" "$OUT/test_agreement.log" | tee -a "$S"
      timeout 400 "$D/rtmpm" validate --backend cuda \
        --case hydrostatic_column_ck,vibrating_bar_ck,dam_break_ck,granular_column_ck \
        --out "$OUT/validation_ck" > "$OUT/validate_ck.log" 2>&1
      say "validate --backend cuda (CK-MPM) rc=$?"
      grep -E "PASS|FAIL|passed|broken|refuse" "$OUT/validate_ck.log" | sed -E 's/ +/ /g' | tee -a "$S"
      timeout 150 "$D/rtmpm" validate --backend cuda --precision f64 --case vibrating_bar_ck \
        --out "$OUT/validation_ck_f64" > "$OUT/validate_ck_f64.log" 2>&1
      say "validate --backend cuda --precision f64 (CK-MPM) rc=$?"
      grep -E "PASS|FAIL|passed|broken|refuse" "$OUT/validate_ck_f64.log" | sed -E 's/ +/ /g' | tee -a "$S"
      ck_bench
      ;;
    ck_speed)
      ck_bench
      RTMPM_CK_AGREEMENT="${CK_AGREEMENT:-ck_p2g=warp;ck_p2g=fused}" t test_agreement cuda_agrees_with_cpu_with_ck_mpm --nocapture
      grep -E "ck-mpm" "$OUT/test_agreement.log" | tee -a "$S"
      ;;
    kernel_ab)
      kernel_ab
      ;;
    kernel_agree)
      for o in ${KERNEL_AGREE_MLS:-}; do
        say "test_agreement, the example scenes in f32 and f64 with $o:"
        RTMPM_AGREEMENT_OPTIONS="$o" t test_agreement every_example_scene --nocapture
        cp "$OUT/test_agreement.log" "$OUT/test_agreement_$o.log"
      done
      if [ "${KERNEL_AGREE_CK:-}" != "none" ]; then
        say "test_agreement, CK-MPM with ${KERNEL_AGREE_CK:-ck_p2g=fused,ck_bound=5,ck_grid=resident}:"
        RTMPM_CK_AGREEMENT="${KERNEL_AGREE_CK:-ck_p2g=fused,ck_bound=5,ck_grid=resident}" \
          t test_agreement cuda_agrees_with_cpu_with_ck_mpm --nocapture
        grep -E "ck-mpm" "$OUT/test_agreement.log" | tee -a "$S"
      fi
      ;;
    validate_compact)
      timeout 500 "$D/rtmpm" validate --backend cuda --particle-state compact --out "$OUT/validation_compact" > "$OUT/validate_compact.log" 2>&1
      say "validate --backend cuda --particle-state compact rc=$?"
      grep -E "PASS|FAIL|passed" "$OUT/validate_compact.log" | sed -E 's/ +/ /g' | tee -a "$S"
      ;;
    convergence)
      timeout 400 "$D/rtmpm" validate --backend cuda --convergence \
        --case vibrating_bar,vibrating_bar_gimp,hydrostatic_column --out "$OUT/convergence" \
        > "$OUT/convergence.log" 2>&1
      say "convergence rc=$?"; grep -E "PASS|FAIL|passed|order" "$OUT/convergence.log" | tee -a "$S"
      timeout 300 "$D/rtmpm" validate --backend cuda --precision f64 \
        --case vibrating_bar,vibrating_bar_gimp,hydrostatic_column,colliding_disks,dam_break \
        --out "$OUT/f64" > "$OUT/f64.log" 2>&1
      say "f64 rc=$?"; grep -E "PASS|FAIL|passed" "$OUT/f64.log" | tee -a "$S"
      ;;
    bench)
      runs=${BENCH_RUNS:-"rtmpm|"}; [ -z "${BENCH_RUNS:-}" ] && [ -x "$D/rtmpm_base" ] && runs="rtmpm_base| rtmpm|"
      for rep in $(seq 1 "${REPS:-2}"); do
        for sc in $CLAYMORE; do
          for r in $runs; do
            bin=${r%%|*}; opts=${r#*|}
            b "${sc%%:*} #$rep ${opts}" "$bin" --scene "bench/${sc%%:*}.toml" --frames "${sc##*:}" ${opts:+--cuda-options "$opts"}
          done
        done
      done
      b "fluid block n=128" rtmpm --n 128 --steps 500
      b "musl scene (bench of MUSL)" rtmpm --scene validation/colliding_disks.toml --frames 2
      ;;
    rigid)
      # The 2M dam break with 10 two-way coupled crates against the same crates as static
      # colliders, interleaved (REPS), then a run of the floating-box example scene.
      for rep in $(seq 1 "${REPS:-2}"); do
        b "dam 2M 10 static crates #$rep" rtmpm --scene bench/fluid_dam_2m_colliders.toml --frames 3
        b "dam 2M 10 floating crates #$rep" rtmpm --scene bench/fluid_dam_2m_bodies.toml --frames 3
        b "dam 2M 10 floating, no overlap #$rep" rtmpm --scene bench/fluid_dam_2m_bodies.toml --frames 3 --cuda-options rigid_overlap=off
      done
      x=$(timeout 300 "$D/rtmpm" run scenes/rigid/floating_box.toml --backend cuda --frames 30 --out "$OUT/floating_box" 2>&1)
      echo "$x" > "$OUT/floating_box.log"
      say "floating_box 30 frames cuda: $(echo "$x" | grep -E 'throughput|^error' | head -2 | tr -s ' ' | tr '\n' ' ')"
      tail -2 "$OUT/floating_box/bodies.csv" 2>/dev/null | tee -a "$S"
      ;;
    ablation)
      for sc in fluid_dam_2m:10 jelly_drop_2m:5; do
        for o in free_zone=off mixed_sort=off warp_reduce=off p2g=shared graph=off fast_math=off g2p2g=off rebuild=kernels sort_fields=29 free_zone=off,sort_fields=29; do
          b "${sc%%:*} $o" rtmpm --scene "bench/${sc%%:*}.toml" --frames "${sc##*:}" --cuda-options "$o"
        done
      done
      ;;
    variants)
      for rep in $(seq 1 "${REPS:-1}"); do
        for sc in ${VARIANT_SCENES:-$CLAYMORE}; do
          for v in ${VARIANTS:-}; do
            IFS='|' read -r label bin defines opts <<< "$v"
            RTMPM_KERNEL_DEFINES="${defines//,/ }" b "${sc%%:*} $label" "$bin" --scene "bench/${sc%%:*}.toml" \
              --frames "${sc##*:}" ${opts:+--cuda-options "$opts"}
          done
        done
      done
      ;;
    profile)
      ncu=$(command -v ncu || ls /opt/nvidia/nsight-compute/*/ncu /usr/local/cuda/bin/ncu 2>/dev/null | head -1)
      # The warp stall reasons by name, as this ncu spells them (cycles stalled per issued instruction).
      stalls=$("$ncu" --query-metrics --chip gh100 2>/dev/null | awk '{print $1}' \
        | grep -E '^smsp__average_warps_issue_stalled_[a-z_]+_per_issue_active$' | sed 's/$/.ratio/' | paste -sd, -)
      extra=$("$ncu" --query-metrics --chip gh100 2>/dev/null | awk '{print $1}' \
        | grep -xE 'lts__t_requests_op_red|lts__t_sectors_op_red|smsp__inst_executed|l1tex__data_pipe_lsu_wavefronts_mem_shared' \
        | sed 's/$/.sum/' | paste -sd, -)
      for r in ${PROFILE_RUNS:-"fluid|rtmpm||fluid_dam_2m"}; do
        IFS='|' read -r label bin defines sc <<< "$r"
        RTMPM_KERNEL_DEFINES="${defines//,/ }" timeout 300 "$ncu" --kernel-name regex:'^g2p2g' --launch-skip 5 \
          --launch-count 1 --set full ${stalls:+--metrics "$stalls${extra:+,$extra}"} \
          "$D/$bin" bench --backend cuda --scene "bench/$sc.toml" --steps 20 > "$OUT/ncu-$label.txt" 2>&1
        say "ncu $label ($bin $defines, $sc) rc=$?"
        grep -E "^  g2p2g|Duration|Compute \(SM\) Throughput|Memory Throughput|DRAM Throughput|L1/TEX Hit|L2 Hit|Issue Slots Busy|Issued Ipc Active|Executed Instructions  |Registers Per|Achieved Occupancy|Theoretical Occupancy|No Eligible|Warp Cycles Per Issued|SM Frequency|L1/TEX Cache Throughput|L2 Cache Throughput|issue_stalled|op_red|inst_executed.sum|mem_shared.sum|ERROR" \
          "$OUT/ncu-$label.txt" | sed -E 's/ +/ /g' | awk '$NF != "0" && $NF != "0.00"' | tee -a "$S"
      done
      ;;
    sanitize)
      cs=$(command -v compute-sanitizer || ls /usr/local/cuda/bin/compute-sanitizer 2>/dev/null | head -1)
      for tool in ${SANITIZE_TOOLS:-memcheck racecheck synccheck}; do
        for a in "--scene bench/snow_1m.toml --steps 20" "--n 64 --steps 20"; do
          timeout 300 "$cs" --tool "$tool" --error-exitcode 9 "$D/rtmpm" bench --backend cuda $a \
            ${SANITIZE_OPTIONS:+--cuda-options "$SANITIZE_OPTIONS"} \
            > "$OUT/sanitize-$tool-$(echo "$a" | tr -c 'a-z0-9' _).log" 2>&1
          rc=$?
          say "compute-sanitizer $tool rtmpm bench $a rc=$rc: $(grep -hE 'ERROR SUMMARY|RACECHECK SUMMARY' "$OUT"/sanitize-$tool-$(echo "$a" | tr -c 'a-z0-9' _).log | tail -1)"
        done
      done
      ;;
    multi)
      for x in $MULTI_GPU_TESTS; do t "$x"; done
      t test_multi_gpu_cli
      for g in 1 2; do b "strong 16.8M gpus=$g" rtmpm --scene bench/strong_16m.toml --frames 2 --gpus "$g"; done
      b "strong 16.8M gpus=1 g2p2g=off" rtmpm --scene bench/strong_16m.toml --frames 2 --cuda-options g2p2g=off
      for o in overlap=off transport=nccl transport=nccl,overlap=off g2p2g=off,overlap=off; do
        b "strong 16.8M gpus=2 $o" rtmpm --scene bench/strong_16m.toml --frames 2 --gpus 2 --cuda-options "$o"
      done
      b "weak 4.2M gpus=1" rtmpm --scene bench/weak_4m_x1.toml --frames 4
      b "weak 8.4M gpus=2" rtmpm --scene bench/weak_4m_x2.toml --frames 4 --gpus 2
      b "weak 8.4M gpus=2 overlap=off" rtmpm --scene bench/weak_4m_x2.toml --frames 4 --gpus 2 --cuda-options overlap=off
      # One process per GPU (NCCL, file rendezvous) against one process driving both through NCCL,
      # the same scene, long enough (12 frames) that NCCL's set-up weighs little; at dt = 5e-5, since
      # the water's impact after the scene's 0.1 s needs it (at 1e-4 one GPU blows up at step 1400 too).
      sed 's/^dt = 1e-4/dt = 5e-5/' bench/strong_16m.toml > /tmp/strong_16m_half_dt.toml
      r=$(timeout 200 "$D/rtmpm" run /tmp/strong_16m_half_dt.toml --frames 12 --no-output --gpus 2 --cuda-options transport=nccl 2>&1)
      echo "$r" >> "$OUT/ranks.log"
      say "strong 16.8M one process, NCCL: $(echo "$r" | grep -E 'throughput|^error' | tr -s ' ')"
      rm -f /tmp/rtmpm-rdv
      for rk in 0 1; do
        timeout 200 "$D/rtmpm" run /tmp/strong_16m_half_dt.toml --frames 12 --no-output --rendezvous file:/tmp/rtmpm-rdv \
          --nccl-ranks 2 --nccl-rank $rk > "$OUT/rank_$rk.log" 2>&1 &
      done
      wait
      say "strong 16.8M two NCCL processes: $(grep -hE 'throughput|^error' "$OUT/rank_0.log" "$OUT/rank_1.log" | tr -s ' ' | tr '\n' ' ')"
      ;;
    multi1)
      for x in $MULTI_GPU_TESTS; do RTMPM_MULTI_GPU_DEVICES=0,0 t "$x" --nocapture; done
      grep -hE "^test |refused with ranks|rigid-body runs|: body [0-9]|particles: \||GPU: particle|runs of several GPUs" \
        $(for x in $MULTI_GPU_TESTS; do echo "$OUT/$x.log"; done) | head -80 | tee -a "$S"
      for g in 1 2; do
        o=""; [ "$g" = 2 ] && o="--gpus 2 --cuda-options devices=0:0"
        x=$(timeout 300 "$D/rtmpm" run scenes/rigid/floating_box.toml --backend cuda --frames 30 $o --out "$OUT/floating_box_$g" 2>&1)
        echo "$x" > "$OUT/floating_box_$g.log"
        say "floating_box 30 frames, ranks=$g: $(echo "$x" | grep -E 'backend|throughput|^error' | head -3 | tr -s ' ' | tr '\n' ' ')"
        tail -1 "$OUT/floating_box_$g/bodies.csv" 2>/dev/null | tee -a "$S"
      done
      ;;
    multi_rigid)
      # One GPU run twice first: how far two runs of one GPU already are (the tolerances' premise).
      t test_multi_gpu_rigid one_gpu_twice_agrees_with_itself_on_the_rigid_scenes --nocapture
      grep -hE "twice #" "$OUT/test_multi_gpu_rigid.log" | cut -c1-220 | tee -a "$S"
      t test_multi_gpu_rigid nccl_ranks_agree_with_one_gpu_on_the_rigid_scenes --nocapture
      grep -hE "^test |skipped|: body [0-9]|particles: \||runs of 2 NCCL ranks" "$OUT/test_multi_gpu_rigid.log" | head -60 | tee -a "$S"
      t test_multi_gpu_cli two_processes_agree_with_one_gpu_on_the_rigid_scenes --nocapture
      grep -hE "^test |skipped|2 processes: body|2 processes: \|d com" "$OUT/test_multi_gpu_cli.log" | head -40 | tee -a "$S"
      ;;
    multi4)
      # 4 GPUs: the agreement tests at 2 and 4 GPUs (RTMPM_MULTI_GPU_COUNTS
      # defaults to 2,4), strong scaling 16.8M on 1, 2, 4 GPUs, weak scaling 4.2M a GPU, and 4 NCCL
      # processes against one process driving the 4 GPUs through NCCL (12 frames at dt = 5e-5).
      for x in $MULTI_GPU_TESTS; do t "$x"; done
      t test_multi_gpu_cli
      for g in 1 2 4; do b "strong 16.8M gpus=$g" rtmpm --scene bench/strong_16m.toml --frames 2 --gpus "$g"; done
      b "strong 16.8M gpus=4 transport=nccl" rtmpm --scene bench/strong_16m.toml --frames 2 --gpus 4 --cuda-options transport=nccl
      b "weak 4.2M gpus=1" rtmpm --scene bench/weak_4m_x1.toml --frames 4
      b "weak 8.4M gpus=2" rtmpm --scene bench/weak_4m_x2.toml --frames 4 --gpus 2
      b "weak 16.8M gpus=4" rtmpm --scene bench/weak_4m_x4.toml --frames 4 --gpus 4
      sed 's/^dt = 1e-4/dt = 5e-5/' bench/strong_16m.toml > /tmp/strong_16m_half_dt.toml
      r=$(timeout 200 "$D/rtmpm" run /tmp/strong_16m_half_dt.toml --frames 12 --no-output --gpus 4 --cuda-options transport=nccl 2>&1)
      echo "$r" >> "$OUT/ranks4.log"
      say "strong 16.8M one process x4, NCCL: $(echo "$r" | grep -E 'throughput|^error' | tr -s ' ')"
      rm -f /tmp/rtmpm-rdv4
      for rk in 0 1 2 3; do
        timeout 200 "$D/rtmpm" run /tmp/strong_16m_half_dt.toml --frames 12 --no-output --rendezvous file:/tmp/rtmpm-rdv4 \
          --nccl-ranks 4 --nccl-rank $rk > "$OUT/rank4_$rk.log" 2>&1 &
      done
      wait
      say "strong 16.8M four NCCL processes: $(grep -hE 'throughput|^error' "$OUT"/rank4_*.log | tr -s ' ' | tr '\n' ' ')"
      ;;
    exchange)
      t test_multi_gpu_agreement the_fused_and_pushed_exchanges_agree_with_one_gpu --nocapture
      grep -hE "runs of the fused|first step differs|aggregates differ|timed out" "$OUT/test_multi_gpu_agreement.log" | head -8 | tee -a "$S"
      ngpu=$(nvidia-smi -L | wc -l)
      red() { grep -E "reduction" "$OUT/bench.log" | tail -1 | sed -E 's/^ +/    /' | tee -a "$S"; }
      # partition=boxes splits 4 GPUs 2 x 2 where it shares less (at 2 GPUs it is the slabs).
      boxes() { [ "$1" -ge 4 ] && echo "partition=boxes exchange=list_push_update,partition=boxes"; }
      for rep in $(seq "${REPS:-2}"); do
        b "weak 4.2M gpus=1 #$rep" rtmpm --scene bench/weak_4m_x1.toml --frames 4
        for g in 2 4; do
          [ "$g" -le "$ngpu" ] || continue
          for o in exchange=kernels exchange=fused exchange=push exchange=push,overlap=off exchange=push_update exchange=list_push_update overlap=off $(boxes "$g"); do
            b "weak gpus=$g $o #$rep" rtmpm --scene "bench/weak_4m_x$g.toml" --frames 4 --gpus "$g" --cuda-options "$o"
            red
          done
        done
      done
      if [ "${EXCHANGE_STRONG:-1}" != 0 ]; then
        b "strong 16.8M gpus=1" rtmpm --scene bench/strong_16m.toml --frames 2
        for g in 2 4; do
          [ "$g" -le "$ngpu" ] || continue
          for o in exchange=kernels exchange=push exchange=push,overlap=off exchange=push_update exchange=list_push_update $(boxes "$g"); do
            b "strong gpus=$g $o" rtmpm --scene bench/strong_16m.toml --frames 2 --gpus "$g" --cuda-options "$o"
            red
          done
        done
      fi
      ;;
    view)
      # The render stage against the simulation (crates/rtmpm-cuda/examples/render_bench.rs): frames
      # without pictures, pictures of that state (events: kernels, copy; host clock: the whole call),
      # frames with a picture each. One summary line per scene and colour mode.
      mkdir -p "$OUT/pictures"
      for sc in fluid_dam_2m:10 snow_1m:20; do
        r=$(RTMPM_BENCH_OUT="$OUT/pictures" timeout 300 "$D/render_bench" "bench/${sc%%:*}.toml" --frames "${sc##*:}" \
            --size 1280x720 --reps 20 --color material,speed 2>&1)
        echo "== render_bench ${sc%%:*}" >> "$OUT/view.log"; echo "$r" >> "$OUT/view.log"
        echo "$r" | grep -E "^(render_bench|picture|frame|error)|particles" | tee -a "$S"
        echo "$r" | grep -E "^render_bench " > "$OUT/view_${sc%%:*}_render.txt"
      done
      # The simulation's step time with the view on against off, like for like
      # (scripts/viewer/view_cost.sh): the same scene, frames 2..N, dt and steps a frame, one
      # binary: `rtmpm bench` (off); `rtmpm view --serve` to frame N without a client, with
      # scripts/viewer/stream_client.py watching (every picture encoded and sent; its pictures/s,
      # draw and JPEG times), and with a client but pictures not overlapped with the steps
      # (RTMPM_VIEW_OVERLAP=0, the loop before). VIEW_FRAMES="scene:N ..." to change.
      port=18180
      for sf in ${VIEW_FRAMES:-fluid_dam_2m:40 snow_1m:400}; do
        bash scripts/viewer/view_cost.sh "$D/rtmpm" cuda "bench/${sf%%:*}.toml" "${sf##*:}" "$OUT" "$port" 1280x720 \
          | tee -a "$S"
        grep -vE '^\{' "$OUT/view_${sf%%:*}_client_client.log" 2>/dev/null | tee -a "$S"
        port=$((port + 10))
      done
      # The short table of the suite, last (scripts/viewer/view_table.py says what each row is).
      python3 scripts/viewer/view_table.py "$OUT" fluid_dam_2m snow_1m | tee -a "$S"
      ;;
    view-soak)
      # Memory over a long stream (scripts/viewer/view_soak.sh): the snow 1.33M streamed at
      # 1280x720 to a client on this machine for VIEW_SOAK_SECONDS (default 600), the server's
      # host (VmRSS) and GPU memory sampled every VIEW_SOAK_EVERY s (30): start, middle, end.
      bash scripts/viewer/view_soak.sh "$D/rtmpm" cuda bench/snow_1m.toml "${VIEW_SOAK_SECONDS:-600}" \
        "$OUT" "${VIEW_SOAK_EVERY:-30}" 18300 1280x720 | tee -a "$S"
      ;;
    long)
      sed 's/^dt = 1e-4/dt = 5e-5/' bench/strong_16m.toml > /tmp/strong_16m_half_dt.toml
      for r in "default||bench/strong_16m.toml" "g2p2g=off|g2p2g=off|bench/strong_16m.toml" \
               "dt=5e-5||/tmp/strong_16m_half_dt.toml"; do
        IFS='|' read -r label opts scene <<< "$r"
        x=$(timeout 240 "$D/rtmpm" run "$scene" --frames 12 --no-output ${opts:+--cuda-options "$opts"} 2>&1)
        echo "== $label" >> "$OUT/long.log"; echo "$x" >> "$OUT/long.log"
        say "strong 16.8M 12 frames 1 GPU $label: $(echo "$x" | grep -E 'throughput|^error|blew|exceeds' | head -3 | tr -s ' ' | tr '\n' ' ')"
      done
      ;;
    python)
      if [ -d "$D/wheels" ]; then
        python3 -m pip install -q --no-index --no-deps --target /tmp/site "$D"/wheels/*.whl && export PYTHONPATH=/tmp/site
        PYTHONUNBUFFERED=1 timeout 500 python3 -m pytest -q crates/rtmpm-py/tests ${PY_K:+-k "$PY_K"} > "$OUT/python.log" 2>&1
        say "python rc=$?: $(tail -1 "$OUT/python.log")"
      else
        say "python: no wheel in $D/wheels"
      fi
      ;;
    cpu)
      # CPU backend scaling: throughput at each thread count and the efficiency
      # rate(T) / (T rate(1)). The warm-up is short: the first steps only sort the particles.
      cores=$(nproc)
      bins=rtmpm; [ -x "$D/rtmpm_base" ] && bins="rtmpm_base rtmpm"
      say "$cores cores; fluid block n=${CPU_N:-128}, ${CPU_STEPS:-100} steps"
      say "$(printf '%-11s %7s %10s %11s %10s  %s' binary threads ms/step 'M p-st/s' efficiency stages_ms)"
      for bin in $bins; do
        r1=""
        for t in ${CPU_THREADS:-1 2 4 8 16}; do
          if [ "$t" -gt "$cores" ]; then say "$bin threads=$t: skipped (only $cores cores)"; continue; fi
          r=$(timeout 400 "$D/$bin" bench --backend cpu --n "${CPU_N:-128}" --steps "${CPU_STEPS:-100}" \
            --warmup 5 --threads "$t" 2>&1)
          echo "== $bin threads=$t" >> "$OUT/cpu.log"; echo "$r" >> "$OUT/cpu.log"
          rate=$(echo "$r" | grep -m1 throughput | grep -oE '\(([0-9.e+]+) particle-steps/s\)' | grep -oE '[0-9.e+]+' | head -1)
          ms=$(echo "$r" | grep -oE '\(([0-9.]+) ms/step\)' | head -1 | tr -d '()' | cut -d' ' -f1)
          k=$(echo "$r" | grep -E '^\s+stage ' | awk '{printf "%s=%s ", $2, $3}')
          mem=$(echo "$r" | grep -m1 'memory       host' | grep -oE 'host [0-9.]+ bytes/particle')
          if [ -z "$rate" ]; then say "$bin threads=$t: no result: $(echo "$r" | grep -iE 'error' | head -1)"; continue; fi
          [ -z "$r1" ] && [ "$t" = 1 ] && r1=$rate
          eff=$(awk -v r="$rate" -v r1="${r1:-0}" -v t="$t" 'BEGIN { if (r1 > 0) printf "%.0f %%", 100 * r / (t * r1); else print "-" }')
          say "$(printf '%-11s %7s %10s %11s %10s  %s %s' "$bin" "$t" "$ms" "$(awk -v r="$rate" 'BEGIN { printf "%.2f", r / 1e6 }')" "$eff" "$k" "$mem")"
        done
      done
      if [ ! -f bench/taichi_mpm3d.py ]; then
        say "taichi: skipped (no bench/taichi_mpm3d.py in this checkout)"
      elif ! python3 -c 'import taichi' > /dev/null 2>&1; then
        say "taichi: skipped (python3 cannot import taichi; carry the taichi==1.7.4 wheel and its needs in .whl, see bench/taichi_mpm3d.py)"
      else
        for t in ${CPU_THREADS:-1 2 4 8 16}; do
          [ "$t" -gt "$cores" ] && continue
          r=$(timeout 400 python3 bench/taichi_mpm3d.py --n "${CPU_N:-128}" --steps "${CPU_STEPS:-100}" --threads "$t" 2>&1)
          echo "== taichi threads=$t" >> "$OUT/cpu.log"; echo "$r" >> "$OUT/cpu.log"
          say "taichi mpm3d threads=$t: $(echo "$r" | grep -m1 -E 'throughput|Error' | tr -s ' ')"
        done
      fi
      ;;
    scale)
      # The big scenes, one process each under /usr/bin/time -v (peak host memory),
      # SCALE_RUNS="scene|cuda-options ..." (default: water 500M, device fill then host fill).
      for r in ${SCALE_RUNS:-"bench/water_500m.toml|fill=device" "bench/water_500m.toml|fill=host"}; do
        sc=${r%%|*}; opts=${r#*|}
        x=$( { /usr/bin/time -v timeout 560 "$D/rtmpm" bench --backend cuda --scene "$sc" --frames 1 --warmup 2 \
              ${opts:+--cuda-options "$opts"}; } 2>&1 )
        echo "== $sc $opts" >> "$OUT/scale.log"; echo "$x" >> "$OUT/scale.log"
        say "scale $sc ${opts}:"
        echo "$x" | grep -E "particles|throughput|set-up|first step|memory  |^error|Maximum resident|Elapsed \(wall" \
          | sed -E 's/^\s+//' | tee -a "$S"
      done
      ;;
    frames)
      t test_frames
      fd=${FRAME_DIR:-/tmp/frames}
      for a in "--scene bench/fluid_dam_2m.toml --frames 2 --frame-formats ply,bgeo,bgeo.gz --frame-whole" \
               "--scene bench/strong_16m.toml --frames 1 --frame-formats ply,bgeo --frame-whole" \
               "--n 584 --steps 200 --frame-formats ply" \
               "--n 584 --steps 200 --frame-formats ply --frame-chunk 4194304"; do
        r=$(timeout 500 "$D/rtmpm" bench --backend cuda $a --frame-write "$fd" 2>&1)
        echo "== rtmpm bench --backend cuda $a --frame-write $fd" >> "$OUT/frames.log"; echo "$r" >> "$OUT/frames.log"
        say "frames $a:"; echo "$r" | grep -E "frame write|copy out|write  |whole  |steps  |^error" | tee -a "$S"
      done
      ;;
    read)
      t test_frames gpu_read_particles_time --nocapture
      grep -E "^read_particles|skipped" "$OUT/test_frames.log" | tee -a "$S"
      mv "$OUT/test_frames.log" "$OUT/test_frames_read.log"
      t test_frames
      ;;
    batch)
      # Many worlds in the same kernels (rtmpm_cuda::batch): isolation, reset and blow-up checks
      # against separate CUDA runs (BATCH_TESTS: tests/batch_isolation.rs, batch_resets.rs,
      # batch_put_slots.rs, batch_rewind.rs, batch_lockstep.rs), then the benchmark (tests/batch_benchmark.rs):
      # BATCH_WORLDS (1024) sand beds of 9,408 particles batched vs one scene of as many particles
      # vs BATCH_ALONE (16) worlds one after another, extrapolated.
      for x in $BATCH_TESTS; do t "$x" --nocapture; done
      timeout "${TEST_TIMEOUT:-500}" "$D/test_batch_benchmark" --include-ignored --test-threads 1 --nocapture --exact batch_benchmark \
        > "$OUT/batch_bench.log" 2>&1
      say "batch_benchmark rc=$?"
      grep -hoE "BENCH.*|panicked.*" "$OUT/batch_bench.log" | tee -a "$S"
      grep -hE "^world|^lockstep|^resumed|^blow-up|refused in" $(for x in $BATCH_TESTS; do echo "$OUT/$x.log"; done) | head -48 | tee -a "$S"
      # The CLI: --backend auto runs the wedge on the GPU (its one-line note), 4 frames with a
      # checkpoint every 2, against a run cut at frame 2 and resumed from its checkpoint_00002:
      # the same files (names) in both folders. Frames stay in a scratch folder, not in $OUT.
      wd=$(mktemp -d)
      timeout 120 "$D/rtmpm" run scenes/wedge_slump.toml --frames 4 --checkpoint-every 2 --out "$wd/whole" > "$OUT/wedge_cli.log" 2>&1
      say "wedge auto rc=$?: $(grep -m1 '^backend:' "$OUT/wedge_cli.log")"
      timeout 120 "$D/rtmpm" run scenes/wedge_slump.toml --frames 2 --checkpoint-every 2 --out "$wd/cut" >> "$OUT/wedge_cli.log" 2>&1 &&
        timeout 120 "$D/rtmpm" run scenes/wedge_slump.toml --frames 4 --resume "$wd/cut/checkpoint_00002" --out "$wd/cut" >> "$OUT/wedge_cli.log" 2>&1
      say "wedge resumed rc=$?: files $(cd "$wd/whole" && find . -type f ! -name '.rtmpm*' | sort | md5sum | cut -c1-8) (uninterrupted) vs $(cd "$wd/cut" && find . -type f ! -name '.rtmpm*' | sort | md5sum | cut -c1-8) (resumed); $(grep -c '^batch of 16 worlds on the GPU' "$OUT/wedge_cli.log") of 3 runs on the GPU"
      rm -rf "$wd"
      ;;
    *) say "unknown suite $suite" ;;
  esac
done
# At most 8 files come back from a device call: every log in one archive, the summary beside it.
(cd "$OUT" && ls | grep -v -e '^summary.txt$' -e '^logs.tgz$' > /tmp/logs.list && \
  tar czf logs.tgz -T /tmp/logs.list && xargs rm -rf < /tmp/logs.list) 2>/dev/null
echo "==== summary"; cat "$S"

//! Assigning particles to GPUs (Fei, Huang & Gao, "Real-Time Simulation of MPM on Modern GPUs" (GTC 2022), "particles are assigned to different GPUs"): spatially
//! coherent slabs of equal particle count along the longest axis of the particles' bounding box,
//! so that few grid blocks are shared ([`slabs`], the default), or (`partition=boxes`) boxes of
//! equal count cut along up to three axes, where that shares fewer blocks per GPU ([`boxes`]: at
//! 4 GPUs a middle slab shares two whole faces, a quarter of a 2 x 2 split two half faces).
//! Deterministic: every process of a multi-process run computes the same partition from the
//! same particles.

pub use crate::options::PartitionKind;
use rtmpm_physics::math::Vec3;
use rtmpm_scene::Scene;
use std::collections::HashMap;

/// The particles of each GPU (original indices, increasing) and the axis the slabs cut.
#[derive(Clone, Debug, PartialEq)]
pub struct Partition {
    /// 0, 1 or 2 (boxes: the axis cut first).
    pub axis: usize,
    /// One list per GPU.
    pub parts: Vec<Vec<u32>>,
}

impl Partition {
    /// Largest particle count of a GPU.
    pub fn max_len(&self) -> usize {
        self.parts.iter().map(Vec::len).max().unwrap_or(0)
    }
}

/// Split `x` into `ranks` slabs of equal count (the first `len % ranks` one larger) along the
/// longest axis of the bounding box; ties in the coordinate are broken by index.
pub fn slabs(x: &[Vec3], ranks: usize) -> Partition {
    let ranks = ranks.max(1);
    let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
    for p in x {
        lo = lo.min(*p);
        hi = hi.max(*p);
    }
    let ext = hi - lo;
    let axis = if ext.x >= ext.y && ext.x >= ext.z {
        0
    } else if ext.y >= ext.z {
        1
    } else {
        2
    };
    let mut order: Vec<u32> = (0..x.len() as u32).collect();
    order.sort_unstable_by(|&a, &b| {
        x[a as usize][axis]
            .total_cmp(&x[b as usize][axis])
            .then(a.cmp(&b))
    });
    let (base, extra) = (x.len() / ranks, x.len() % ranks);
    let mut parts = Vec::with_capacity(ranks);
    let mut start = 0;
    for r in 0..ranks {
        let len = base + usize::from(r < extra);
        let mut p = order[start..start + len].to_vec();
        p.sort_unstable();
        parts.push(p);
        start += len;
    }
    Partition { axis, parts }
}

/// Split `x` between `ranks` GPUs as `kind` says.
pub fn split(x: &[Vec3], ranks: usize, kind: PartitionKind) -> Partition {
    match kind {
        PartitionKind::Slabs => slabs(x, ranks),
        PartitionKind::Boxes => boxes(x, ranks),
    }
}

/// The extent of the particles' bounding box (zero without particles).
fn extent(x: &[Vec3]) -> Vec3 {
    let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
    for p in x {
        lo = lo.min(*p);
        hi = hi.max(*p);
    }
    if x.is_empty() { Vec3::ZERO } else { hi - lo }
}

/// The cut area a piece shares with its neighbours, at most (a piece inside the split: two
/// faces along an axis cut into 3 or more, one along an axis cut in two), for a box of extent
/// `e` cut into `counts[a]` pieces of equal size along axis a.
fn worst_cut_area(e: Vec3, counts: [usize; 3]) -> f64 {
    let e = [e.x as f64, e.y as f64, e.z as f64];
    let mut area = 0.0;
    for a in 0..3 {
        if counts[a] < 2 {
            continue;
        }
        let faces = if counts[a] == 2 { 1.0 } else { 2.0 };
        let (b, c) = ((a + 1) % 3, (a + 2) % 3);
        area += faces * (e[b] / counts[b] as f64) * (e[c] / counts[c] as f64);
    }
    area
}

/// The pieces along each axis of [`boxes`] for `ranks` GPUs and a bounding box of extent `e`:
/// of every factorisation of `ranks` into three counts, the one whose worst piece shares the
/// least cut area ([`worst_cut_area`]); ties go to the one found first (fewer axes cut first,
/// then x before y before z), so that a slab split stays a slab split along the longest axis.
pub fn box_counts(ranks: usize, e: Vec3) -> [usize; 3] {
    let ranks = ranks.max(1);
    let mut candidates = Vec::new();
    for a in 1..=ranks {
        for b in 1..=ranks / a {
            if ranks.is_multiple_of(a * b) {
                candidates.push([a, b, ranks / (a * b)]);
            }
        }
    }
    // Fewer axes cut first, then x's count before y's before z's (decreasing).
    candidates.sort_by_key(|c| (c.iter().filter(|&&n| n > 1).count(), std::cmp::Reverse(*c)));
    let mut best = candidates[0];
    let mut best_area = worst_cut_area(e, best);
    for &c in &candidates[1..] {
        let area = worst_cut_area(e, c);
        // Strictly less by more than rounding: a tie keeps the simpler split.
        if area < best_area * (1.0 - 1e-9) {
            best = c;
            best_area = area;
        }
    }
    best
}

/// Split `x` into `ranks` boxes of equal count (the first ones one larger where the count does
/// not divide): [`box_counts`] pieces along each axis, cut along the axis of most pieces first
/// (by coordinate, ties by index), then each piece along the next axis, and so on. Ranks go in
/// the order of the pieces (the first axis's piece, then the next's). `axis` is the first axis
/// cut. A split along one axis is [`slabs`] along it.
pub fn boxes(x: &[Vec3], ranks: usize) -> Partition {
    let ranks = ranks.max(1);
    let counts = box_counts(ranks, extent(x));
    let mut axes = [0usize, 1, 2];
    // Most pieces first; ties in axis order.
    axes.sort_by_key(|&a| std::cmp::Reverse(counts[a]));
    let mut pieces: Vec<Vec<u32>> = vec![(0..x.len() as u32).collect()];
    for &axis in &axes {
        if counts[axis] < 2 {
            continue;
        }
        pieces = pieces
            .into_iter()
            .flat_map(|p| cut_by_count(x, p, axis, counts[axis]))
            .collect();
    }
    for p in &mut pieces {
        p.sort_unstable();
    }
    Partition {
        axis: axes[0],
        parts: pieces,
    }
}

/// The particles `ids` cut into `n` pieces of equal count along `axis` (the first `len % n`
/// one larger), by coordinate with ties by index.
fn cut_by_count(x: &[Vec3], mut ids: Vec<u32>, axis: usize, n: usize) -> Vec<Vec<u32>> {
    ids.sort_unstable_by(|&a, &b| {
        x[a as usize][axis]
            .total_cmp(&x[b as usize][axis])
            .then(a.cmp(&b))
    });
    let (base, extra) = (ids.len() / n, ids.len() % n);
    let mut out = Vec::with_capacity(n);
    let mut start = 0;
    for r in 0..n {
        let len = base + usize::from(r < extra);
        out.push(ids[start..start + len].to_vec());
        start += len;
    }
    out
}

/// The gblock of a particle at `x` (as `CudaBackend` computes it: the block of the stencil base).
fn gblock(scene: &Scene, x: Vec3) -> [i32; 3] {
    let origin = scene.domain_min - 4.0 * scene.dx;
    let base = ((x - origin) / scene.dx - 0.5).floor().as_ivec3();
    [base.x >> 2, base.y >> 2, base.z >> 2]
}

/// Number of grid blocks that more than one GPU touches (pblocks: the 3x3x3 neighbourhoods of
/// the gblocks), for sizing the shared-block reduction before the first step.
pub fn shared_blocks(scene: &Scene, x: &[Vec3], p: &Partition) -> usize {
    let mut owners: HashMap<[i32; 3], u64> = HashMap::new();
    for (r, part) in p.parts.iter().enumerate() {
        let mut g: Vec<[i32; 3]> = part.iter().map(|&i| gblock(scene, x[i as usize])).collect();
        g.sort_unstable();
        g.dedup();
        for b in g {
            for t in 0..27 {
                let q = [b[0] + t / 9 - 1, b[1] + t / 3 % 3 - 1, b[2] + t % 3 - 1];
                *owners.entry(q).or_insert(0) |= 1u64 << (r % 64);
            }
        }
    }
    owners.values().filter(|m| m.count_ones() >= 2).count()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slabs_are_equal_coherent_and_cover_every_particle() {
        // A 20 x 4 x 4 row of points, shuffled: slabs must cut along x.
        let mut x = Vec::new();
        for i in 0..20 {
            for j in 0..4 {
                for k in 0..4 {
                    x.push(Vec3::new(i as f32 * 0.1, j as f32 * 0.01, k as f32 * 0.01));
                }
            }
        }
        x.reverse();
        let p = slabs(&x, 3);
        assert_eq!(p.axis, 0);
        let lens: Vec<usize> = p.parts.iter().map(Vec::len).collect();
        assert_eq!(lens, vec![107, 107, 106]);
        let mut all: Vec<u32> = p.parts.concat();
        all.sort_unstable();
        assert_eq!(all, (0..320).collect::<Vec<u32>>());
        // Every x of slab r is <= every x of slab r + 1.
        for r in 0..2 {
            let max_r = p.parts[r]
                .iter()
                .map(|&i| x[i as usize].x)
                .fold(f32::MIN, f32::max);
            let min_n = p.parts[r + 1]
                .iter()
                .map(|&i| x[i as usize].x)
                .fold(f32::MAX, f32::min);
            assert!(max_r <= min_n);
        }
        // Indices increase inside each part.
        assert!(p.parts.iter().all(|v| v.windows(2).all(|w| w[0] < w[1])));
        assert_eq!(slabs(&x, 1).parts[0].len(), 320);
    }

    /// The shared blocks each rank holds (the blocks of `shared_blocks`, counted per holder).
    fn shared_per_rank(scene: &Scene, x: &[Vec3], p: &Partition) -> Vec<usize> {
        let mut owners: HashMap<[i32; 3], u64> = HashMap::new();
        for (r, part) in p.parts.iter().enumerate() {
            for &i in part {
                let b = gblock(scene, x[i as usize]);
                for t in 0..27 {
                    let q = [b[0] + t / 9 - 1, b[1] + t / 3 % 3 - 1, b[2] + t % 3 - 1];
                    *owners.entry(q).or_insert(0) |= 1u64 << r;
                }
            }
        }
        (0..p.parts.len())
            .map(|r| {
                owners
                    .values()
                    .filter(|m| m.count_ones() >= 2 && *m >> r & 1 == 1)
                    .count()
            })
            .collect()
    }

    #[test]
    fn box_counts_cut_the_least_area_and_keep_slabs_where_they_are_best() {
        // Two GPUs: one cut, across the longest axis (x on a tie), as the slabs cut.
        assert_eq!(box_counts(2, Vec3::new(1.0, 1.0, 1.0)), [2, 1, 1]);
        assert_eq!(box_counts(2, Vec3::new(0.5, 1.0, 0.7)), [1, 2, 1]);
        assert_eq!(box_counts(2, Vec3::new(0.5, 0.5, 0.7)), [1, 1, 2]);
        // A long row: slabs (a middle slab's two faces are the smallest there).
        assert_eq!(box_counts(4, Vec3::new(20.0, 1.0, 1.0)), [4, 1, 1]);
        // A cube: 2 x 2 (two half faces a piece, where a middle slab shares two whole ones).
        assert_eq!(box_counts(4, Vec3::new(1.0, 1.0, 1.0)), [2, 2, 1]);
        // The weak benchmark of 4 GPUs (water 1.0 x 0.25 x 0.5 m): 2 along x, 2 along z.
        assert_eq!(box_counts(4, Vec3::new(1.0, 0.25, 0.5)), [2, 1, 2]);
        assert!(
            worst_cut_area(Vec3::new(1.0, 0.25, 0.5), [2, 1, 2])
                < worst_cut_area(Vec3::new(1.0, 0.25, 0.5), [4, 1, 1])
        );
        // Eight in a cube: 2 x 2 x 2; a prime count is a slab split.
        assert_eq!(box_counts(8, Vec3::new(1.0, 1.0, 1.0)), [2, 2, 2]);
        assert_eq!(box_counts(3, Vec3::new(1.0, 1.0, 2.0)), [1, 1, 3]);
        assert_eq!(box_counts(1, Vec3::new(1.0, 1.0, 1.0)), [1, 1, 1]);
    }

    #[test]
    fn boxes_of_two_are_slabs_and_boxes_of_four_share_fewer_blocks_a_gpu() {
        let scene = Scene::from_toml(
            "name = \"t\"\n[domain]\nmin = [0,0,0]\nmax = [1,1,1]\ndx = 0.0078125\n\
             [time]\nduration = 1\nfps = 10\ndt = 1e-3\n\
             [[material]]\nname = \"w\"\ntype = \"fluid\"\ndensity = 1000\nbulk_modulus = 1e4\n\
             [[body]]\nmaterial = \"w\"\nshape = \"box\"\nmin = [0.25,0.25,0.25]\nmax = [0.75,0.75,0.75]\n\
             particles_per_cell = 1\n",
            "<test>",
        )
        .unwrap();
        let mut x = scene.sample_particles().unwrap().x;
        x.reverse();
        assert_eq!(boxes(&x, 2), slabs(&x, 2));
        assert_eq!(split(&x, 2, PartitionKind::Boxes), slabs(&x, 2));
        assert_eq!(split(&x, 4, PartitionKind::Slabs), slabs(&x, 4));
        let four = boxes(&x, 4);
        let lens: Vec<usize> = four.parts.iter().map(Vec::len).collect();
        let n = x.len();
        assert!(
            lens.iter().all(|&l| l == n / 4 || l == n / 4 + 1),
            "{lens:?}"
        );
        let mut all: Vec<u32> = four.parts.concat();
        all.sort_unstable();
        assert_eq!(all, (0..n as u32).collect::<Vec<u32>>());
        assert!(four.parts.iter().all(|v| v.windows(2).all(|w| w[0] < w[1])));
        // Each piece is a box: the bounding boxes of two pieces overlap by no more than a
        // plane (that of a tie in the coordinate of a cut).
        let bounds: Vec<(Vec3, Vec3)> = four
            .parts
            .iter()
            .map(|p| {
                p.iter().fold(
                    (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
                    |(lo, hi), &i| (lo.min(x[i as usize]), hi.max(x[i as usize])),
                )
            })
            .collect();
        for i in 0..4 {
            for j in i + 1..4 {
                let (a, b) = (bounds[i], bounds[j]);
                let overlap = a.1.min(b.1) - a.0.max(b.0);
                assert!(
                    overlap.min_element() <= 0.0,
                    "pieces {i} and {j} overlap: {a:?} {b:?}"
                );
            }
        }
        let slab = slabs(&x, 4);
        let (b, s) = (
            shared_per_rank(&scene, &x, &four),
            shared_per_rank(&scene, &x, &slab),
        );
        let worst = |v: &[usize]| v.iter().copied().max().unwrap_or(0);
        // A middle slab shares two 64 x 64-cell faces; a quarter of 2 x 2 two half faces (and
        // the corner column): the worst GPU holds about half the shared blocks.
        assert!(
            (worst(&b) as f64) < 0.7 * worst(&s) as f64,
            "boxes {b:?}, slabs {s:?}"
        );
        println!("shared blocks a GPU, 4 GPUs: boxes {b:?}, slabs {s:?}");
    }

    #[test]
    fn shared_blocks_of_two_slabs_are_the_blocks_near_the_cut() {
        let scene = Scene::from_toml(
            "name = \"t\"\n[domain]\nmin = [0,0,0]\nmax = [1,1,1]\ndx = 0.0625\n\
             [time]\nduration = 1\nfps = 10\ndt = 1e-3\n\
             [[material]]\nname = \"w\"\ntype = \"fluid\"\ndensity = 1000\nbulk_modulus = 1e4\n\
             [[body]]\nmaterial = \"w\"\nshape = \"box\"\nmin = [0.2,0.2,0.2]\nmax = [0.8,0.4,0.4]\n",
            "<test>",
        )
        .unwrap();
        let p = scene.sample_particles().unwrap();
        let one = slabs(&p.x, 1);
        assert_eq!(shared_blocks(&scene, &p.x, &one), 0);
        let two = slabs(&p.x, 2);
        let s = shared_blocks(&scene, &p.x, &two);
        // The cut is a plane x = const: the shared blocks form a slab a few blocks thick across
        // the (y, z) extent of the pblocks, far fewer than all pblocks.
        assert!(s > 0, "{s}");
        let all = {
            let mut g: Vec<[i32; 3]> = p.x.iter().map(|&x| gblock(&scene, x)).collect();
            g.sort_unstable();
            g.dedup();
            g.len()
        };
        assert!(s < 27 * all / 2, "{s} shared of {all} gblocks");
    }
}

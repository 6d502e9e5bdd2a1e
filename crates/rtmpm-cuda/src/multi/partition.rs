//! Assigning particles to GPUs (Fei, Huang & Gao, "Real-Time Simulation of MPM on Modern GPUs" (GTC 2022), "particles are assigned to different GPUs"): spatially
//! coherent slabs of equal particle count along the longest axis of the particles' bounding box,
//! so that few grid blocks are shared. Deterministic: every process of a multi-process run
//! computes the same partition from the same particles.

use rtmpm_physics::math::Vec3;
use rtmpm_scene::Scene;
use std::collections::HashMap;

/// The particles of each GPU (original indices, increasing) and the axis the slabs cut.
#[derive(Clone, Debug, PartialEq)]
pub struct Partition {
    /// 0, 1 or 2.
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

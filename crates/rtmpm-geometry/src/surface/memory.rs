//! The memory a surface reconstruction needs, estimated before it starts: splashsurf lists every
//! particle's neighbours within the kernel's support, so a dense cluster (100,000 particles at
//! one point, as a blow-up or an emitter that piles its particles up leaves) asks for
//! `n^2` entries, gigabytes, and the allocation would abort the process. The estimate refuses
//! such input with the numbers instead.

use glam::Vec3;
use rustc_hash::FxHashMap;

/// Bytes per neighbour entry (an index) with a margin for the lists' own overhead and the ghost
/// particles of splashsurf's subdomains.
const BYTES_PER_NEIGHBOUR: f64 = 10.0;
/// Bytes per particle besides its neighbours: its position copies, density, the subdomain
/// bookkeeping and the marching-cubes grid around it (rounded up from the reconstruction of a
/// uniform block, where the neighbours are about 60 % of the peak).
pub const BYTES_PER_PARTICLE: u64 = 400;

/// The estimate for one set of positions.
#[derive(Clone, Debug, PartialEq)]
pub struct SurfaceMemory {
    /// Neighbour entries (pairs of particles within the kernel's support, counted from both
    /// sides), estimated.
    pub neighbours: f64,
    /// Bytes of the reconstruction, estimated.
    pub bytes: u64,
    /// The most particles in one cell of the support's size, and its centre.
    pub densest: (u64, Vec3),
}

/// Estimate the memory of reconstructing the surface around `positions` with a kernel of
/// support radius `support` (m). Pairs are counted on cells of edge `support`: all pairs in one
/// cell, and of the pairs with the 26 cells around it the fraction of that block a support
/// sphere covers, `(4/3) pi / 27`. Exact for a cluster of coincident points; within about 20 %
/// for a uniform fluid. Non-finite positions are skipped (the reconstruction skips them too).
pub fn estimate(positions: &[Vec3], support: f32) -> SurfaceMemory {
    let h = support.max(f32::MIN_POSITIVE) as f64;
    let mut cells: FxHashMap<[i64; 3], u64> = FxHashMap::default();
    let mut n = 0u64;
    for p in positions.iter().filter(|p| p.is_finite()) {
        let c = (p.as_dvec3() / h).floor();
        *cells
            .entry([c.x as i64, c.y as i64, c.z as i64])
            .or_default() += 1;
        n += 1;
    }
    let near = 4.0 / 3.0 * std::f64::consts::PI / 27.0;
    let mut pairs = 0.0f64;
    let mut densest = (0u64, [0i64; 3]);
    for (&c, &k) in &cells {
        if k > densest.0 {
            densest = (k, c);
        }
        let mut around = 0u64;
        for dz in -1..=1 {
            for dy in -1..=1 {
                for dx in -1..=1 {
                    if (dx, dy, dz) != (0, 0, 0) {
                        let key = [c[0] + dx, c[1] + dy, c[2] + dz];
                        around += cells.get(&key).copied().unwrap_or(0);
                    }
                }
            }
        }
        pairs += k as f64 * (k as f64 + near * around as f64);
    }
    let bytes = pairs * BYTES_PER_NEIGHBOUR + n as f64 * BYTES_PER_PARTICLE as f64;
    let centre = |i: i64| (i as f64 + 0.5) * h;
    SurfaceMemory {
        neighbours: pairs,
        bytes: bytes.min(u64::MAX as f64) as u64,
        densest: (
            densest.0,
            Vec3::new(
                centre(densest.1[0]) as f32,
                centre(densest.1[1]) as f32,
                centre(densest.1[2]) as f32,
            ),
        ),
    }
}

impl SurfaceMemory {
    /// An error when the estimate is above `available` bytes (`None`: unknown, not checked),
    /// naming the densest cell.
    pub fn check(&self, n: usize, available: Option<u64>) -> Result<(), String> {
        let Some(avail) = available else {
            return Ok(());
        };
        if self.bytes <= avail {
            return Ok(());
        }
        let human = |b: u64| format!("{:.2} GiB", b as f64 / (1u64 << 30) as f64);
        let (k, c) = self.densest;
        Err(format!(
            "the surface of {n} particles would need about {} of memory ({:.3e} neighbour \
             entries), more than the {} available: {k} particles lie within one kernel support \
             around ({:.4}, {:.4}, {:.4}), far denser than a fluid at rest (a blow-up or an \
             emitter that piles its particles up leaves such clusters); fix the run that made \
             them, or mesh fewer particles (--materials, [surface] materials)",
            human(self.bytes),
            self.neighbours,
            human(avail),
            c.x,
            c.y,
            c.z
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_coincident_cluster_is_counted_whole() {
        let pts = vec![Vec3::new(0.3, 0.3, 0.3); 100_000];
        let m = estimate(&pts, 0.01);
        assert_eq!(m.neighbours, 1e10);
        assert!(m.bytes >= 100_000_000_000, "{}", m.bytes);
        assert_eq!(m.densest.0, 100_000);
        let e = m.check(pts.len(), Some(8 << 30)).unwrap_err();
        assert!(
            e.contains("100000 particles lie within one kernel support"),
            "{e}"
        );
        assert!(m.check(pts.len(), None).is_ok());
    }

    #[test]
    fn a_uniform_block_is_near_its_true_neighbour_count() {
        // A lattice of spacing 1, support 2.5: each point has 64 others within 2.5 (exact:
        // counted below), the estimate within 25 %.
        let k = 30;
        let mut pts = Vec::new();
        for i in 0..k {
            for j in 0..k {
                for l in 0..k {
                    pts.push(Vec3::new(i as f32, j as f32, l as f32));
                }
            }
        }
        let h = 2.5f32;
        let exact = (-3i32..=3)
            .flat_map(|a| (-3i32..=3).flat_map(move |b| (-3i32..=3).map(move |c| (a, b, c))))
            .filter(|&(a, b, c)| ((a * a + b * b + c * c) as f32).sqrt() <= h)
            .count() as f64;
        let m = estimate(&pts, h);
        // Interior points only are full; compare per point away from the faces.
        let per_point = m.neighbours / pts.len() as f64;
        assert!(per_point < 1.25 * exact, "{per_point} vs {exact}");
        assert!(per_point > 0.5 * exact, "{per_point} vs {exact}");
        assert!(m.check(pts.len(), Some(1 << 30)).is_ok());
    }
}

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

/// How many times the neighbour entries of a fluid at rest of as many particles a
/// reconstruction may ask for. The work grows with the entries: a cluster of `k` particles
/// within one support adds `k^2` of them, and 100,000 coincident particles take splashsurf many
/// more than a minute on 16 cores where memory allows them at all. Material packed to `c` times
/// its rest density has `c` times the rest figure, and no material of a run that went well is
/// packed 20 times; a cluster must hold about `sqrt(19 * 77 n)` particles at one point to pass
/// it (38,000 in a scene of a million).
pub const MOST_NEIGHBOURS_OVER_REST: f64 = 20.0;

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

/// Neighbour entries a particle has in a fluid at rest, counted as [`estimate`] counts them:
/// particles of radius `particle_radius` (the radius of a sphere of the particle's volume)
/// fill a cell of edge `support` with `support^3 / V` of them, each with the cell's others and
/// the support sphere's share of the 26 cells around.
pub fn rest_neighbours(particle_radius: f32, support: f32) -> f64 {
    let v = 4.0 / 3.0 * std::f64::consts::PI * (particle_radius as f64).powi(3);
    let per_cell = (support as f64).powi(3) / v.max(f64::MIN_POSITIVE);
    let near = 4.0 / 3.0 * std::f64::consts::PI / 27.0;
    per_cell * (1.0 + near * 26.0)
}

impl SurfaceMemory {
    /// An error when the neighbour entries are more than [`MOST_NEIGHBOURS_OVER_REST`] times
    /// those of `n` particles of a fluid at rest (`rest_per_particle`, [`rest_neighbours`]),
    /// naming the densest cell: the reconstruction would run for minutes or hours, whatever the
    /// memory.
    pub fn check_work(&self, n: usize, rest_per_particle: f64) -> Result<(), String> {
        let rest = n as f64 * rest_per_particle;
        if self.neighbours <= MOST_NEIGHBOURS_OVER_REST * rest {
            return Ok(());
        }
        let (k, c) = self.densest;
        Err(format!(
            "the surface of {n} particles would need about {:.3e} neighbour entries, {:.0} times \
             the {:.3e} of a fluid at rest of as many particles (at most {} times is meshed): {k} \
             particles lie within one kernel support around ({:.4}, {:.4}, {:.4}), where a fluid at \
             rest has about {:.0} (a blow-up or an emitter that piles its particles up leaves such \
             clusters); fix the run that made them, or mesh fewer particles (--materials, \
             [surface] materials)",
            self.neighbours,
            self.neighbours / rest.max(f64::MIN_POSITIVE),
            rest,
            MOST_NEIGHBOURS_OVER_REST,
            c.x,
            c.y,
            c.z,
            rest_per_particle / (1.0 + 4.0 / 3.0 * std::f64::consts::PI / 27.0 * 26.0),
        ))
    }

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
        // Whatever the memory: far more work than a fluid at rest (support 4 particle radii).
        let e = m
            .check_work(pts.len(), rest_neighbours(0.0025, 0.01))
            .unwrap_err();
        assert!(
            e.contains("100000 particles lie within one kernel support"),
            "{e}"
        );
        assert!(e.contains("times the"), "{e}");
    }

    #[test]
    fn a_fluid_at_rest_has_its_rest_neighbours() {
        // Particles of radius r on a lattice of their volume's spacing ((4/3 pi)^(1/3) r), a
        // support of 4 r: the estimate per interior particle is near rest_neighbours, so the
        // work check passes, also with a cluster of a hundredth of its particles added at one
        // point; with a quarter of them there, it does not.
        let r = 0.01f32;
        let spacing = (4.0 / 3.0 * std::f32::consts::PI).cbrt() * r;
        let k = 40;
        let mut pts = Vec::new();
        for i in 0..k {
            for j in 0..k {
                for l in 0..k {
                    pts.push(Vec3::new(i as f32, j as f32, l as f32) * spacing);
                }
            }
        }
        let support = 4.0 * r;
        let rest = rest_neighbours(r, support);
        assert!((70.0..85.0).contains(&rest), "{rest}");
        let m = estimate(&pts, support);
        let per_point = m.neighbours / pts.len() as f64;
        assert!(
            per_point < 1.25 * rest && per_point > 0.5 * rest,
            "{per_point} vs {rest}"
        );
        assert!(m.check_work(pts.len(), rest).is_ok());
        let n = pts.len();
        let mut small = pts.clone();
        small.extend(std::iter::repeat_n(Vec3::splat(0.2), n / 100));
        assert!(
            estimate(&small, support)
                .check_work(small.len(), rest)
                .is_ok()
        );
        pts.extend(std::iter::repeat_n(Vec3::splat(0.2), n / 4));
        let m = estimate(&pts, support);
        let e = m.check_work(pts.len(), rest).unwrap_err();
        // The cluster's cell: its 16,000 and the few lattice points that share it.
        assert!((16_000..16_100).contains(&m.densest.0), "{:?}", m.densest);
        assert!(
            e.contains(&format!(
                "{} particles lie within one kernel support",
                m.densest.0
            )),
            "{e}"
        );
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

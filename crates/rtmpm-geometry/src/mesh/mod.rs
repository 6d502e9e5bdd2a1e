//! Triangle meshes from OBJ files and their signed distance grids.
//!
//! [`MeshSdf::build`] samples the signed distance of a closed triangle mesh on a regular grid:
//!
//! 1. exact point-triangle distances (Ericson's closest point) in a narrow band of two grid
//!    cells around every triangle, remembering the closest triangle of each grid point;
//! 2. closest-triangle propagation sweeps (Bridson's `makelevelset3` scheme) to fill the rest of
//!    the grid with (nearly exact) distances;
//! 3. the sign from ray parity along the three axes with a majority vote (robust to a ray
//!    grazing an edge), rays slightly perturbed so that they do not hit vertices exactly.
//!
//! Queries interpolate trilinearly; normals are central differences of the interpolant; outside
//! the grid the distance to the grid box is added to the value at the nearest grid point.

use glam::Vec3;

/// A triangle mesh (positions and vertex-index triples).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TriMesh {
    pub vertices: Vec<Vec3>,
    pub triangles: Vec<[u32; 3]>,
}

/// Why a mesh could not be loaded.
#[derive(Debug, thiserror::Error)]
pub enum MeshError {
    #[error("cannot read mesh file {path}: {source}")]
    Io {
        path: String,
        source: std::io::Error,
    },
    #[error("cannot parse OBJ file {path}: {message}")]
    Parse { path: String, message: String },
    #[error("mesh file {path} holds no triangles")]
    Empty { path: String },
    #[error("mesh file {path} has a face referring to vertex {index} of {count}")]
    BadIndex {
        path: String,
        index: u32,
        count: usize,
    },
    #[error("mesh file {path} has a non-finite vertex coordinate")]
    NonFinite { path: String },
}

impl TriMesh {
    /// Parse OBJ text (all objects, faces triangulated), then scale about the origin and
    /// translate: `x' = x * scale + translate`; `name` is used in error messages (the file
    /// is read by `rtmpm_io::obj::read_obj`).
    #[allow(clippy::unnecessary_cast)]
    pub fn parse_obj(
        bytes: &[u8],
        name: &str,
        scale: Vec3,
        translate: Vec3,
    ) -> Result<TriMesh, MeshError> {
        let opts = tobj::LoadOptions {
            triangulate: true,
            single_index: false,
            ignore_points: true,
            ignore_lines: true,
        };
        let mut reader = std::io::BufReader::new(bytes);
        let (models, _) =
            tobj::load_obj_buf(&mut reader, &opts, |_| Err(tobj::LoadError::OpenFileFailed))
                .map_err(|e| MeshError::Parse {
                    path: name.to_string(),
                    message: e.to_string(),
                })?;
        let mut mesh = TriMesh::default();
        for m in &models {
            let base = mesh.vertices.len() as u32;
            let p = &m.mesh.positions;
            for v in p.chunks_exact(3) {
                let x = Vec3::new(v[0] as f32, v[1] as f32, v[2] as f32) * scale + translate;
                if !x.is_finite() {
                    return Err(MeshError::NonFinite {
                        path: name.to_string(),
                    });
                }
                mesh.vertices.push(x);
            }
            let count = p.len() / 3;
            for t in m.mesh.indices.chunks_exact(3) {
                for &i in t {
                    if i as usize >= count {
                        return Err(MeshError::BadIndex {
                            path: name.to_string(),
                            index: i,
                            count,
                        });
                    }
                }
                mesh.triangles.push([base + t[0], base + t[1], base + t[2]]);
            }
        }
        if mesh.triangles.is_empty() {
            return Err(MeshError::Empty {
                path: name.to_string(),
            });
        }
        Ok(mesh)
    }

    /// Surface area: the sum of the triangles' areas.
    pub fn area(&self) -> f32 {
        self.triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| self.vertices[i as usize]);
                0.5 * (b - a).cross(c - a).length()
            })
            .sum()
    }

    /// Axis-aligned bounds of the vertices.
    pub fn bounds(&self) -> (Vec3, Vec3) {
        let mut lo = Vec3::splat(f32::INFINITY);
        let mut hi = Vec3::splat(f32::NEG_INFINITY);
        for v in &self.vertices {
            lo = lo.min(*v);
            hi = hi.max(*v);
        }
        (lo, hi)
    }

    fn tri(&self, t: usize) -> (Vec3, Vec3, Vec3) {
        let [a, b, c] = self.triangles[t];
        (
            self.vertices[a as usize],
            self.vertices[b as usize],
            self.vertices[c as usize],
        )
    }
}

/// Closest point to `p` on triangle `abc` (Ericson, Real-Time Collision Detection, 5.1.5).
pub fn closest_point_on_triangle(p: Vec3, a: Vec3, b: Vec3, c: Vec3) -> Vec3 {
    let ab = b - a;
    let ac = c - a;
    let ap = p - a;
    let d1 = ab.dot(ap);
    let d2 = ac.dot(ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return a;
    }
    let bp = p - b;
    let d3 = ab.dot(bp);
    let d4 = ac.dot(bp);
    if d3 >= 0.0 && d4 <= d3 {
        return b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return a + v * ab;
    }
    let cp = p - c;
    let d5 = ab.dot(cp);
    let d6 = ac.dot(cp);
    if d6 >= 0.0 && d5 <= d6 {
        return c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return a + w * ac;
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return b + w * (c - b);
    }
    let denom = 1.0 / (va + vb + vc);
    if !denom.is_finite() {
        // Degenerate triangle: nearest of its three edges' end points.
        return [a, b, c]
            .into_iter()
            .min_by(|x, y| {
                (p - *x)
                    .length_squared()
                    .total_cmp(&(p - *y).length_squared())
            })
            .unwrap_or(a);
    }
    let v = vb * denom;
    let w = vc * denom;
    a + ab * v + ac * w
}

/// A signed distance field sampled on a regular grid around a closed triangle mesh.
#[derive(Clone, Debug, PartialEq)]
pub struct MeshSdf {
    /// Position of grid point (0, 0, 0).
    pub origin: Vec3,
    pub spacing: f32,
    pub dims: [u32; 3],
    /// Distances, x fastest.
    pub values: Vec<f32>,
    /// Bounds of the mesh itself (the grid extends a margin beyond them).
    pub mesh_min: Vec3,
    pub mesh_max: Vec3,
}

/// Largest number of grid points per axis; coarser spacing is used beyond it.
pub const MAX_DIM: u32 = 192;

impl MeshSdf {
    /// Sample the signed distance of a closed mesh (see the module docs). The spacing is
    /// enlarged if the grid would exceed [`MAX_DIM`] points along an axis.
    pub fn build(mesh: &TriMesh, spacing: f32, margin: u32) -> MeshSdf {
        let (lo, hi) = mesh.bounds();
        let extent = (hi - lo).max(Vec3::splat(1e-6));
        let lattice = Lattice::around(lo, extent, spacing, margin);
        let (mut dist, mut closest) = lattice.narrow_band(mesh);
        lattice.propagate(mesh, &mut dist, &mut closest);
        let votes = lattice.inside_votes(mesh);
        let values = dist
            .iter()
            .zip(&votes)
            .map(|(&d, &v)| {
                let d = if d.is_finite() { d } else { extent.length() };
                if v >= 2 { -d } else { d }
            })
            .collect();
        MeshSdf {
            origin: lattice.origin,
            spacing: lattice.h,
            dims: lattice.dims,
            values,
            mesh_min: lo,
            mesh_max: hi,
        }
    }

    /// Upper corner of the grid.
    pub fn grid_max(&self) -> Vec3 {
        self.origin
            + Vec3::new(
                (self.dims[0] - 1) as f32,
                (self.dims[1] - 1) as f32,
                (self.dims[2] - 1) as f32,
            ) * self.spacing
    }

    fn value(&self, i: usize, j: usize, k: usize) -> f32 {
        let [nx, ny, _] = self.dims.map(|d| d as usize);
        self.values[i + nx * (j + ny * k)]
    }

    /// Signed distance (trilinear interpolation inside the grid; outside it, the distance to
    /// the grid box plus the value at the nearest grid point, which is positive).
    pub fn distance(&self, x: Vec3) -> f32 {
        let gmax = self.grid_max();
        let clamped = x.clamp(self.origin, gmax);
        let outside = (x - clamped).length();
        let g = (clamped - self.origin) / self.spacing;
        let mut base = [0usize; 3];
        let mut frac = [0f32; 3];
        for a in 0..3 {
            let d = self.dims[a] as usize;
            if d < 2 {
                base[a] = 0;
                frac[a] = 0.0;
                continue;
            }
            let b = (g[a].floor().max(0.0) as usize).min(d - 2);
            base[a] = b;
            frac[a] = (g[a] - b as f32).clamp(0.0, 1.0);
        }
        let mut v = 0.0;
        for corner in 0..8 {
            let o = [corner & 1, (corner >> 1) & 1, (corner >> 2) & 1];
            let mut w = 1.0;
            let mut ix = [0usize; 3];
            for a in 0..3 {
                let d = self.dims[a] as usize;
                ix[a] = (base[a] + o[a]).min(d - 1);
                w *= if o[a] == 1 { frac[a] } else { 1.0 - frac[a] };
            }
            if w != 0.0 {
                v += w * self.value(ix[0], ix[1], ix[2]);
            }
        }
        v + outside
    }

    /// Outward unit normal: central differences of [`MeshSdf::distance`] with step half a cell.
    pub fn normal(&self, x: Vec3) -> Vec3 {
        let e = 0.5 * self.spacing;
        let g = Vec3::new(
            self.distance(x + Vec3::X * e) - self.distance(x - Vec3::X * e),
            self.distance(x + Vec3::Y * e) - self.distance(x - Vec3::Y * e),
            self.distance(x + Vec3::Z * e) - self.distance(x - Vec3::Z * e),
        );
        g.try_normalize().unwrap_or(Vec3::Y)
    }

    /// Volume enclosed by the mesh, estimated from the grid (grid cells whose centre
    /// interpolates to a negative distance).
    pub fn volume(&self) -> f32 {
        let [nx, ny, nz] = self.dims.map(|d| d as usize);
        let mut count = 0usize;
        for k in 0..nz.saturating_sub(1) {
            for j in 0..ny.saturating_sub(1) {
                for i in 0..nx.saturating_sub(1) {
                    let mut s = 0.0;
                    for c in 0..8 {
                        s += self.value(i + (c & 1), j + ((c >> 1) & 1), k + ((c >> 2) & 1));
                    }
                    if s < 0.0 {
                        count += 1;
                    }
                }
            }
        }
        count as f32 * self.spacing.powi(3)
    }
}

/// The grid points of a [`MeshSdf`] being built: `dims` points `h` apart from `origin`, x
/// fastest.
struct Lattice {
    origin: Vec3,
    h: f32,
    dims: [u32; 3],
}

impl Lattice {
    /// The grid around a mesh whose bounds start at `lo` and span `extent`: `margin` (at least
    /// one) points beyond them on every side, at `spacing` (a 32nd of the largest extent when it
    /// is not a positive number) or coarser where [`MAX_DIM`] points would not reach.
    fn around(lo: Vec3, extent: Vec3, spacing: f32, margin: u32) -> Lattice {
        let margin = margin.max(1);
        let mut h = if spacing.is_finite() && spacing > 0.0 {
            spacing
        } else {
            extent.max_element() / 32.0
        };
        let max_cells = (MAX_DIM - 1 - 2 * margin) as f32;
        h = h.max(extent.max_element() / max_cells);
        let origin = lo - Vec3::splat(margin as f32 * h);
        let dims = [0, 1, 2].map(|a| ((extent[a] / h).ceil() as u32 + 1 + 2 * margin).min(MAX_DIM));
        Lattice { origin, h, dims }
    }

    /// Number of grid points.
    fn len(&self) -> usize {
        self.dims.iter().map(|&d| d as usize).product()
    }

    /// Storage index of point (i, j, k).
    fn idx(&self, i: usize, j: usize, k: usize) -> usize {
        let [nx, ny, _] = self.dims.map(|d| d as usize);
        i + nx * (j + ny * k)
    }

    /// Position of point (i, j, k).
    fn pos(&self, i: usize, j: usize, k: usize) -> Vec3 {
        self.origin + Vec3::new(i as f32, j as f32, k as f32) * self.h
    }

    /// The point index along axis `a` at or below (`up`: at or above) coordinate `x`, clamped to
    /// the grid.
    fn to_index(&self, x: f32, a: usize, up: bool) -> usize {
        let g = (x - self.origin[a]) / self.h;
        let g = if up { g.ceil() } else { g.floor() };
        (g.max(0.0) as usize).min(self.dims[a] as usize - 1)
    }

    /// Step 1: exact distances within two cells of every triangle, and the closest triangle of
    /// each point reached (`u32::MAX` elsewhere, where the distance is infinite).
    fn narrow_band(&self, mesh: &TriMesh) -> (Vec<f32>, Vec<u32>) {
        let n = self.len();
        let mut dist = vec![f32::INFINITY; n];
        let mut closest = vec![u32::MAX; n];
        let band = 2.0 * self.h;
        for t in 0..mesh.triangles.len() {
            let (a, b, c) = mesh.tri(t);
            let tlo = a.min(b).min(c) - Vec3::splat(band);
            let thi = a.max(b).max(c) + Vec3::splat(band);
            let (i0, i1) = (
                self.to_index(tlo.x, 0, false),
                self.to_index(thi.x, 0, true),
            );
            let (j0, j1) = (
                self.to_index(tlo.y, 1, false),
                self.to_index(thi.y, 1, true),
            );
            let (k0, k1) = (
                self.to_index(tlo.z, 2, false),
                self.to_index(thi.z, 2, true),
            );
            for k in k0..=k1 {
                for j in j0..=j1 {
                    for i in i0..=i1 {
                        let p = self.pos(i, j, k);
                        let d = (p - closest_point_on_triangle(p, a, b, c)).length();
                        let id = self.idx(i, j, k);
                        if d < dist[id] {
                            dist[id] = d;
                            closest[id] = t as u32;
                        }
                    }
                }
            }
        }
        (dist, closest)
    }

    /// Step 2: the closest triangle handed on to the neighbours by sweeping in the 8 diagonal
    /// directions, twice; a point takes a neighbour's triangle when it is nearer.
    fn propagate(&self, mesh: &TriMesh, dist: &mut [f32], closest: &mut [u32]) {
        let [nx, ny, nz] = self.dims.map(|d| d as usize);
        for _ in 0..2 {
            for dir in 0..8 {
                let di: isize = if dir & 1 == 0 { 1 } else { -1 };
                let dj: isize = if dir & 2 == 0 { 1 } else { -1 };
                let dk: isize = if dir & 4 == 0 { 1 } else { -1 };
                let range = |d: isize, len: usize| -> Vec<usize> {
                    if d > 0 {
                        (1..len).collect()
                    } else {
                        (0..len.saturating_sub(1)).rev().collect()
                    }
                };
                let (ri, rj, rk) = (range(di, nx), range(dj, ny), range(dk, nz));
                for &k in &rk {
                    for &j in &rj {
                        for &i in &ri {
                            let behind = (
                                (i as isize - di) as usize,
                                (j as isize - dj) as usize,
                                (k as isize - dk) as usize,
                            );
                            self.take_nearer(mesh, (i, j, k), behind, dist, closest);
                        }
                    }
                }
            }
        }
    }

    /// Point `(i, j, k)` takes the closest triangle of any of its 7 neighbours towards `behind`
    /// (the point one step back along the sweep) when that triangle is nearer than its own.
    fn take_nearer(
        &self,
        mesh: &TriMesh,
        (i, j, k): (usize, usize, usize),
        (pi, pj, pk): (usize, usize, usize),
        dist: &mut [f32],
        closest: &mut [u32],
    ) {
        let p = self.pos(i, j, k);
        let id = self.idx(i, j, k);
        let neighbours = [
            self.idx(pi, j, k),
            self.idx(i, pj, k),
            self.idx(pi, pj, k),
            self.idx(i, j, pk),
            self.idx(pi, j, pk),
            self.idx(i, pj, pk),
            self.idx(pi, pj, pk),
        ];
        for nb in neighbours {
            let t = closest[nb];
            if t != u32::MAX && t != closest[id] {
                let (a, b, c) = mesh.tri(t as usize);
                let d = (p - closest_point_on_triangle(p, a, b, c)).length();
                if d < dist[id] {
                    dist[id] = d;
                    closest[id] = t;
                }
            }
        }
    }

    /// Step 3: for every point, along how many of the three axes a ray from it has crossed the
    /// mesh an odd number of times (inside by majority: 2 or 3).
    fn inside_votes(&self, mesh: &TriMesh) -> Vec<u8> {
        let mut votes = vec![0u8; self.len()];
        for axis in 0..3 {
            let (b, c) = ((axis + 1) % 3, (axis + 2) % 3);
            let (nb, nc, na) = (
                self.dims[b] as usize,
                self.dims[c] as usize,
                self.dims[axis] as usize,
            );
            let hits = self.ray_hits(mesh, axis);
            for jc in 0..nc {
                for jb in 0..nb {
                    let line = &hits[jb + nb * jc];
                    let mut crossed = 0usize;
                    for ia in 0..na {
                        let x = self.origin[axis] as f64 + ia as f64 * self.h as f64;
                        while crossed < line.len() && line[crossed] < x {
                            crossed += 1;
                        }
                        if crossed % 2 == 1 {
                            let mut g = [0usize; 3];
                            g[axis] = ia;
                            g[b] = jb;
                            g[c] = jc;
                            votes[self.idx(g[0], g[1], g[2])] += 1;
                        }
                    }
                }
            }
        }
        votes
    }

    /// Where the rays along `axis` through the grid's lines (slightly perturbed so that they do
    /// not pass exactly through edges) cross the mesh: per line (the other two axes' indices
    /// `jb + nb * jc`), the crossing coordinates along `axis`, sorted.
    fn ray_hits(&self, mesh: &TriMesh, axis: usize) -> Vec<Vec<f64>> {
        let (origin, h) = (self.origin, self.h);
        let (b, c) = ((axis + 1) % 3, (axis + 2) % 3);
        let (nb, nc) = (self.dims[b] as usize, self.dims[c] as usize);
        // Tiny fixed perturbation of the rays so they do not pass exactly through edges.
        let eps_b = 1.234_567e-4 * h as f64;
        let eps_c = 7.654_321e-5 * h as f64;
        let mut hits: Vec<Vec<f64>> = vec![Vec::new(); nb * nc];
        for t in 0..mesh.triangles.len() {
            let (p0, p1, p2) = mesh.tri(t);
            let v = [p0, p1, p2].map(|p| [p[axis] as f64, p[b] as f64, p[c] as f64]);
            let lo_b = v.iter().map(|p| p[1]).fold(f64::INFINITY, f64::min);
            let hi_b = v.iter().map(|p| p[1]).fold(f64::NEG_INFINITY, f64::max);
            let lo_c = v.iter().map(|p| p[2]).fold(f64::INFINITY, f64::min);
            let hi_c = v.iter().map(|p| p[2]).fold(f64::NEG_INFINITY, f64::max);
            let gb = |x: f64, up: bool| {
                let g = (x - origin[b] as f64) / h as f64;
                let g = if up { g.ceil() } else { g.floor() };
                (g.max(0.0) as usize).min(nb - 1)
            };
            let gc = |x: f64, up: bool| {
                let g = (x - origin[c] as f64) / h as f64;
                let g = if up { g.ceil() } else { g.floor() };
                (g.max(0.0) as usize).min(nc - 1)
            };
            for jc in gc(lo_c, false)..=gc(hi_c, true) {
                let qc = origin[c] as f64 + jc as f64 * h as f64 + eps_c;
                for jb in gb(lo_b, false)..=gb(hi_b, true) {
                    let qb = origin[b] as f64 + jb as f64 * h as f64 + eps_b;
                    // 2D barycentric coordinates of (qb, qc) in the projected triangle.
                    let w0 = orient(v[1][1], v[1][2], v[2][1], v[2][2], qb, qc);
                    let w1 = orient(v[2][1], v[2][2], v[0][1], v[0][2], qb, qc);
                    let w2 = orient(v[0][1], v[0][2], v[1][1], v[1][2], qb, qc);
                    let inside = (w0 >= 0.0 && w1 >= 0.0 && w2 >= 0.0)
                        || (w0 <= 0.0 && w1 <= 0.0 && w2 <= 0.0);
                    let sum = w0 + w1 + w2;
                    if inside && sum != 0.0 {
                        let s = (w0 * v[0][0] + w1 * v[1][0] + w2 * v[2][0]) / sum;
                        hits[jb + nb * jc].push(s);
                    }
                }
            }
        }
        for line in &mut hits {
            line.sort_by(f64::total_cmp);
        }
        hits
    }
}

/// Twice the signed area of the 2D triangle (a, b, q).
#[inline]
fn orient(ax: f64, ay: f64, bx: f64, by: f64, qx: f64, qy: f64) -> f64 {
    (bx - ax) * (qy - ay) - (by - ay) * (qx - ax)
}

#[cfg(test)]
#[cfg(test)]
mod tests;

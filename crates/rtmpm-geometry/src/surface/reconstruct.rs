//! The reconstruction itself, through `splashsurf_lib` (cargo feature `surface`).

use super::mesh::TriMesh;
use super::params::SurfaceParams;
use glam::Vec3;
use splashsurf_lib::mesh::Mesh3d;
use splashsurf_lib::nalgebra::Vector3;
use splashsurf_lib::{Parameters, postprocessing, reconstruct_surface};

/// Reconstruct the surface around `positions` (non-finite positions are skipped). Returns an
/// empty mesh for fewer than one particle; errors carry splashsurf's message. `available`:
/// the memory the reconstruction may take (`None`: unknown); input that needs more (a dense
/// cluster of particles, [`super::memory`]) is refused before it starts.
pub fn reconstruct(
    positions: &[Vec3],
    params: &SurfaceParams,
    available: Option<u64>,
) -> Result<TriMesh, String> {
    params.check()?;
    let pts: Vec<Vector3<f32>> = positions
        .iter()
        .filter(|p| p.is_finite())
        .map(|p| Vector3::new(p.x, p.y, p.z))
        .collect();
    if pts.is_empty() {
        return Ok(TriMesh::default());
    }
    let r = params.particle_radius;
    let support = 2.0 * params.smoothing_length * r;
    // Dense clusters would ask splashsurf for n^2 neighbour entries: refused before it starts,
    // for the work they make (any machine) and for the memory (this machine).
    let needs = super::memory::estimate(positions, support);
    needs.check_work(pts.len(), super::memory::rest_neighbours(r, support))?;
    needs.check(pts.len(), available)?;
    let mut sp = Parameters::new(r, support, params.cube_size * r);
    sp.iso_surface_threshold = params.threshold;
    let recon = reconstruct_surface::<i64, f32>(&pts, &sp)
        .map_err(|e| format!("surface reconstruction failed: {e:#}"))?;
    let mut mesh = recon.mesh;
    if mesh.triangles.is_empty() {
        return Ok(TriMesh::default());
    }
    let connectivity = (params.smoothing_iters > 0 || params.normal_smoothing_iters > 0)
        .then(|| mesh.vertex_vertex_connectivity());
    if let Some(conn) = &connectivity
        && params.smoothing_iters > 0
    {
        let weights = vec![1.0f32; mesh.vertices.len()];
        postprocessing::par_laplacian_smoothing_inplace(
            &mut mesh,
            conn,
            params.smoothing_iters as usize,
            0.5,
            &weights,
        );
    }
    let mut normals: Vec<Vector3<f32>> = mesh
        .par_vertex_normals()
        .into_iter()
        .map(|n| n.into_inner())
        .collect();
    if let Some(conn) = &connectivity
        && params.normal_smoothing_iters > 0
    {
        postprocessing::par_laplacian_smoothing_normals_inplace(
            &mut normals,
            conn,
            params.normal_smoothing_iters as usize,
        );
    }
    let n_vert = mesh.vertices.len();
    if n_vert > u32::MAX as usize {
        return Err(format!("the surface has {n_vert} vertices, more than 2^32"));
    }
    Ok(TriMesh {
        vertices: mesh
            .vertices
            .iter()
            .map(|v| Vec3::new(v.x, v.y, v.z))
            .collect(),
        normals: normals
            .iter()
            .map(|n| Vec3::new(n.x, n.y, n.z).normalize_or(Vec3::Y))
            .collect(),
        triangles: mesh
            .triangles
            .iter()
            .map(|t| [t[0] as u32, t[1] as u32, t[2] as u32])
            .collect(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::surface::SurfaceParams;

    /// A ball of radius `r_ball` filled with particles on a lattice of spacing `h`.
    fn ball(r_ball: f32, h: f32) -> Vec<Vec3> {
        let k = (r_ball / h).ceil() as i32;
        let mut v = Vec::new();
        for i in -k..=k {
            for j in -k..=k {
                for l in -k..=k {
                    let p = Vec3::new(i as f32, j as f32, l as f32) * h;
                    if p.length() <= r_ball {
                        v.push(p + Vec3::new(1.0, 2.0, 3.0));
                    }
                }
            }
        }
        v
    }

    #[test]
    fn ball_of_particles_gives_a_closed_outward_ball() {
        let h = 0.01;
        let r_ball = 0.1;
        let pts = ball(r_ball, h);
        let params = SurfaceParams::for_volume(h * h * h);
        let m = reconstruct(&pts, &params, None).unwrap();
        m.check().unwrap();
        assert!(m.triangles.len() > 1000, "{} triangles", m.triangles.len());
        assert_eq!(m.normals.len(), m.vertices.len());
        // Every vertex near the ball's surface (within a particle spacing and a half).
        let c = Vec3::new(1.0, 2.0, 3.0);
        for v in &m.vertices {
            let d = (*v - c).length() - r_ball;
            assert!(d.abs() < 1.5 * h, "vertex {v} at {d} from the sphere");
        }
        // Normals point outwards, and the enclosed volume is that of the ball within 15%.
        let outward = m
            .vertices
            .iter()
            .zip(&m.normals)
            .filter(|(v, n)| n.dot((**v - c).normalize()) > 0.8)
            .count();
        assert!(outward as f64 > 0.98 * m.vertices.len() as f64);
        let exact = 4.0 / 3.0 * std::f64::consts::PI * (r_ball as f64).powi(3);
        let vol = m.volume();
        assert!((vol / exact - 1.0).abs() < 0.15, "volume {vol} vs {exact}");
    }

    #[test]
    fn empty_input_and_bad_params() {
        let p = SurfaceParams::for_volume(1e-6);
        assert!(reconstruct(&[], &p, None).unwrap().is_empty());
        assert!(reconstruct(&[Vec3::NAN], &p, None).unwrap().is_empty());
        let mut bad = p;
        bad.threshold = 1.5;
        assert!(reconstruct(&[Vec3::ZERO], &bad, None).is_err());
    }
}

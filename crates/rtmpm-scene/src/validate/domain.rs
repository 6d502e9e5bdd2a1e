//! The `[domain]` table and the grid: the box, a whole number of cells of `dx` per axis.

use super::core::{R, V, fmt3};
use crate::schema::RawDomain;
use rtmpm_physics::math::Vec3;

impl V<'_> {
    /// The domain's min and max corners and the grid spacing `dx`.
    pub(super) fn domain(&self, raw: &RawDomain) -> R<(Vec3, Vec3, f32)> {
        let dx = self.positive("domain.dx", raw.dx, "the grid spacing dx")?;
        let dmin = self.vec3("domain.min", raw.min)?;
        let dmax = self.vec3("domain.max", raw.max)?;
        for a in 0..3 {
            if dmax[a] <= dmin[a] {
                return Err(self.err(
                    format!("domain.max[{a}]"),
                    format!(
                        "domain max {} is not above min {} along axis {a}",
                        fmt3(dmax),
                        fmt3(dmin)
                    ),
                    "make every component of max larger than that of min",
                ));
            }
        }
        let cells = (dmax - dmin) / dx;
        for a in 0..3 {
            let n = cells[a];
            if n.round() < 1.0 {
                return Err(self.err(
                    "domain.dx",
                    format!(
                        "dx = {dx} is larger than the domain along axis {a} ({} m)",
                        dmax[a] - dmin[a]
                    ),
                    "use a dx that divides the domain into cells (e.g. a 64th of its size)",
                ));
            }
            if (n - n.round()).abs() > 1e-3 * n.max(1.0) {
                let fixed = dmin[a] + n.round().max(1.0) * dx;
                return Err(self.err(
                    format!("domain.max[{a}]"),
                    format!("the domain is {n} cells long along axis {a}, not a whole number of cells of dx = {dx}"),
                    format!("set domain.max[{a}] = {fixed} (a whole number of cells) or change dx"),
                ));
            }
            if n.round() > 4096.0 {
                return Err(self.err(
                    "domain.dx",
                    format!("{} cells along axis {a} is too many", n.round()),
                    "use a larger dx (at most 4096 cells per axis)",
                ));
            }
        }
        Ok((dmin, dmax, dx))
    }
}

//! Colours: the viridis colour map for scalar fields and the material palette.

/// Viridis sampled at 0, 0.1, ..., 1 (matplotlib's values), linearly interpolated.
const VIRIDIS: [[f32; 3]; 11] = [
    [0.267004, 0.004874, 0.329415],
    [0.282623, 0.140926, 0.457517],
    [0.253935, 0.265254, 0.529983],
    [0.206756, 0.371758, 0.553117],
    [0.163625, 0.471133, 0.558148],
    [0.127568, 0.566949, 0.550556],
    [0.134692, 0.658636, 0.517649],
    [0.266941, 0.748751, 0.440573],
    [0.477504, 0.821444, 0.318195],
    [0.741388, 0.873449, 0.149561],
    [0.993248, 0.906157, 0.143936],
];

/// Viridis colour (linear 0..1 RGB) of `t`, clamped to [0, 1]; NaN maps to 0.
pub fn viridis(t: f32) -> [f32; 3] {
    let t = if t.is_nan() { 0.0 } else { t.clamp(0.0, 1.0) };
    let s = t * 10.0;
    let i = (s.floor() as usize).min(9);
    let f = s - i as f32;
    let (a, b) = (VIRIDIS[i], VIRIDIS[i + 1]);
    [
        a[0] + (b[0] - a[0]) * f,
        a[1] + (b[1] - a[1]) * f,
        a[2] + (b[2] - a[2]) * f,
    ]
}

/// The fixed material palette (by material index, repeating): blue, sand, red, green, white,
/// purple, orange, teal.
pub const PALETTE: [[f32; 3]; 8] = [
    [0.20, 0.48, 0.92],
    [0.86, 0.70, 0.42],
    [0.88, 0.22, 0.25],
    [0.35, 0.75, 0.30],
    [0.92, 0.93, 0.96],
    [0.60, 0.38, 0.82],
    [0.98, 0.58, 0.15],
    [0.15, 0.72, 0.70],
];

/// Colour of material `index` in the fixed palette.
pub fn material_color(index: u32) -> [f32; 3] {
    PALETTE[index as usize % PALETTE.len()]
}

/// 8-bit value of a 0..1 channel (clamped).
#[inline]
pub fn to_u8(c: f32) -> u8 {
    (c.clamp(0.0, 1.0) * 255.0 + 0.5) as u8
}

/// Colour per material of a scene: each model's own colour (`Constitutive::COLOUR`: fluids
/// blue, sand sand-coloured, snow white, elastic solids red, ...); a colour already taken by an
/// earlier material goes to the first free entry of the palette instead. Shared by the command
/// line and the Python package.
pub fn scene_palette(scene: &rtmpm_scene::Scene) -> Vec<[f32; 3]> {
    let mut taken: Vec<[f32; 3]> = Vec::new();
    scene
        .materials
        .iter()
        .map(|m| {
            let own = m.model.colour();
            let c = if taken.contains(&own) {
                PALETTE
                    .iter()
                    .copied()
                    .find(|p| !taken.contains(p))
                    .unwrap_or(own)
            } else {
                own
            };
            taken.push(c);
            c
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn viridis_ends_and_clamping() {
        assert_eq!(viridis(0.0), VIRIDIS[0]);
        assert_eq!(viridis(1.0), VIRIDIS[10]);
        assert_eq!(viridis(-3.0), VIRIDIS[0]);
        assert_eq!(viridis(7.0), VIRIDIS[10]);
        assert_eq!(viridis(f32::NAN), VIRIDIS[0]);
        let m = viridis(0.55);
        for k in 0..3 {
            let (lo, hi) = (
                VIRIDIS[5][k].min(VIRIDIS[6][k]),
                VIRIDIS[5][k].max(VIRIDIS[6][k]),
            );
            assert!(m[k] >= lo && m[k] <= hi);
        }
    }
}

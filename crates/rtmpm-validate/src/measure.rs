//! Extracting measured quantities from sampled signals.

/// Sampled curve points (x, y).
pub type Curve = Vec<(f64, f64)>;

/// Period and amplitude of an oscillating signal sampled at times `t`: the period is twice the
/// mean spacing of its zero crossings (linearly interpolated), the amplitude the mean of the
/// largest |value| between consecutive crossings (including the start, where the signal is at a
/// crest for a cosine). None when fewer than two crossings are found.
pub fn period_and_amplitude(t: &[f64], y: &[f64]) -> Option<(f64, f64)> {
    let mut crossings = Vec::new();
    for i in 1..y.len() {
        let (a, b) = (y[i - 1], y[i]);
        if (a > 0.0 && b <= 0.0) || (a < 0.0 && b >= 0.0) {
            let s = a / (a - b);
            crossings.push(t[i - 1] + s * (t[i] - t[i - 1]));
        }
    }
    if crossings.len() < 2 {
        return None;
    }
    let spacing = (crossings[crossings.len() - 1] - crossings[0]) / (crossings.len() - 1) as f64;
    // Extremes: between the start and the first crossing, and between consecutive crossings.
    let mut peaks = Vec::new();
    let mut bounds = vec![t[0] - 1.0];
    bounds.extend(&crossings);
    for w in bounds.windows(2) {
        let peak = t
            .iter()
            .zip(y)
            .filter(|(ti, _)| **ti > w[0] && **ti < w[1])
            .map(|(_, yi)| yi.abs())
            .fold(0.0, f64::max);
        peaks.push(peak);
    }
    let amplitude = peaks.iter().sum::<f64>() / peaks.len() as f64;
    Some((2.0 * spacing, amplitude))
}

/// Least-squares line `y = a + b x`; returns (a, b).
pub fn fit_line(x: &[f64], y: &[f64]) -> (f64, f64) {
    let n = x.len() as f64;
    let (sx, sy) = (x.iter().sum::<f64>(), y.iter().sum::<f64>());
    let sxx = x.iter().map(|v| v * v).sum::<f64>();
    let sxy = x.iter().zip(y).map(|(a, b)| a * b).sum::<f64>();
    let b = (n * sxy - sx * sy) / (n * sxx - sx * sx);
    ((sy - b * sx) / n, b)
}

/// Observed order of convergence from errors at resolutions refined by `ratio` each time.
pub fn observed_order(errors: &[f64], ratio: f64) -> Vec<f64> {
    errors
        .windows(2)
        .map(|w| (w[0] / w[1]).ln() / ratio.ln())
        .collect()
}

/// Relative error in percent.
pub fn rel_pct(simulated: f64, reference: f64) -> f64 {
    100.0 * (simulated - reference).abs() / reference.abs()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn period_and_amplitude_of_a_sampled_cosine() {
        let t: Vec<f64> = (0..=600).map(|i| i as f64 * 0.05).collect();
        let y: Vec<f64> = t.iter().map(|t| 0.06366 * (0.6283 * t).cos()).collect();
        let (p, a) = period_and_amplitude(&t, &y).expect("oscillates");
        assert!(
            (p - 2.0 * std::f64::consts::PI / 0.6283).abs() < 1e-3,
            "period {p}"
        );
        assert!((a - 0.06366).abs() < 1e-4, "amplitude {a}");
        // A damped one has a smaller mean amplitude; a constant has none.
        let yd: Vec<f64> = t
            .iter()
            .map(|t| 0.06366 * (-0.05 * t).exp() * (0.6283 * t).cos())
            .collect();
        assert!(period_and_amplitude(&t, &yd).expect("oscillates").1 < 0.05);
        assert!(period_and_amplitude(&t, &vec![1.0; t.len()]).is_none());
    }

    #[test]
    fn line_fit_recovers_slope_and_intercept() {
        let x = [0.0, 1.0, 2.0, 3.0];
        let y: Vec<f64> = x.iter().map(|x| 2.5 - 4.0 * x).collect();
        let (a, b) = fit_line(&x, &y);
        assert!((a - 2.5).abs() < 1e-12 && (b + 4.0).abs() < 1e-12);
    }
}

//! Host-time diagnostics switched on by an environment variable: [`PartTimes`] sums the parts of
//! a call (a batch's reset, a pose, a put) and prints their means to stderr every 100 calls.

use std::sync::{Mutex, OnceLock};
use std::time::Instant;

/// Calls summed between prints.
const EVERY: u32 = 100;

/// The host time of a call's `N` parts, summed over calls and printed to stderr as means every
/// 100 calls when the environment variable `var` is `1` (read once); off by default, at the cost
/// of one check of a flag a call. Made in a `static`:
/// `static RESETS: PartTimes<2> = PartTimes::new("RTMPM_RESET_TIMING", "reset", "worlds",
/// ["start states", "driver's reset"]);`
pub struct PartTimes<const N: usize> {
    var: &'static str,
    what: &'static str,
    items: &'static str,
    parts: [&'static str; N],
    on: OnceLock<bool>,
    /// Calls, items, seconds of each part.
    sums: Mutex<(u32, usize, [f64; N])>,
}

impl<const N: usize> PartTimes<N> {
    /// The times of `what`'s `parts`, each call about some number of `items`, printed when the
    /// environment variable `var` is `1`.
    pub const fn new(
        var: &'static str,
        what: &'static str,
        items: &'static str,
        parts: [&'static str; N],
    ) -> PartTimes<N> {
        PartTimes {
            var,
            what,
            items,
            parts,
            on: OnceLock::new(),
            sums: Mutex::new((0, 0, [0.0; N])),
        }
    }

    /// The variable is set: time the calls (a caller may skip taking its instants otherwise).
    pub fn on(&self) -> bool {
        *self
            .on
            .get_or_init(|| std::env::var(self.var).is_ok_and(|v| v.trim() == "1"))
    }

    /// One call about `items` items whose part `i` ran from `start[i]` to `start[i + 1]`
    /// (`end` after the last); the means printed every 100 calls.
    pub fn record(&self, items: usize, start: [Instant; N], end: Instant) {
        if !self.on() {
            return;
        }
        let mut s = self.sums.lock().unwrap_or_else(|p| p.into_inner());
        s.0 += 1;
        s.1 += items;
        for i in 0..N {
            let until = if i + 1 < N { start[i + 1] } else { end };
            s.2[i] += (until - start[i]).as_secs_f64();
        }
        if s.0 == EVERY {
            eprintln!("{}", self.line(s.1, &s.2));
            *s = (0, 0, [0.0; N]);
        }
    }

    /// The printed line for `items` items and `seconds` per part over [`EVERY`] calls.
    fn line(&self, items: usize, seconds: &[f64; N]) -> String {
        let parts: Vec<String> = self
            .parts
            .iter()
            .zip(seconds)
            .map(|(p, s)| format!("{p} {:.1} us", 1e6 * s / EVERY as f64))
            .collect();
        format!(
            "{} {} (mean of {EVERY} calls, {} {} a call): {}",
            self.var,
            self.what,
            items / EVERY as usize,
            self.items,
            parts.join(", ")
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_line_names_every_part_with_its_mean() {
        static T: PartTimes<2> =
            PartTimes::new("RTMPM_NO_SUCH_TIMING", "reset", "worlds", ["a", "b"]);
        assert!(!T.on());
        assert_eq!(
            T.line(400, &[100e-6, 250e-6]),
            "RTMPM_NO_SUCH_TIMING reset (mean of 100 calls, 4 worlds a call): a 1.0 us, b 2.5 us"
        );
        // Off: nothing summed.
        let t = Instant::now();
        T.record(4, [t, t], t);
        assert_eq!(T.sums.lock().unwrap().0, 0);
    }
}

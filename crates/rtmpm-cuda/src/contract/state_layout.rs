//! The particle state's layout: which word of a particle holds which field, chosen once per
//! backend ([`StateLayout::choose`]) and emitted into the kernels' prelude as the `F_*` and
//! `RTMPM_NFIELDS` defines they use ([`StateLayout::defines`], selected by
//! `-DRTMPM_STATE_LAYOUT=code`). The host asks the layout for every offset (pack, unpack,
//! export, the sort's field mask, the emitters, the multi-GPU exchange, Python).
//!
//! Structure of arrays: word `w` of particle slot `i` at `w * cap + i` (`cap`: the capacity).
//!
//! | layout | x | v | C | F | plastic | mass | vol0 | material | id | words |
//! |---|---|---|---|---|---|---|---|---|---|---|
//! | `Full` | 0..3 | 3..6 | 6..15 | 15..24 | 24 | 25 | 26 | 27 | 28 | 29 |
//! | `Fluid` | 0..3 | 3..6 | 6..15 | 15 (J^(1/3)) | - | 16 | 17 | 18 | 19 | 20 |
//! | `Compact` | 0..3 | 3..6 | 6..11 (codec) | 11..20 | 20 | 21 | 22 | 23 | 24 | 25 |
//! | `CompactFluid` | 0..3 | 3..6 | 6..11 (codec) | 11 (J^(1/3)) | - | 12 | 13 | 14 | 15 | 16 |
//!
//! `Fluid` layouts (every material a fluid, whose F is J^(1/3) I) keep F's diagonal value
//! J^(1/3) in one word and no plastic word (a fluid has none). `Compact` layouts keep APIC's C
//! in the shared-exponent format of [`crate::state::codec`] (f32 build only; the velocity stays f32:
//! the codec's module doc says why).

/// Where a particle's fields are in the state arrays.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub enum StateLayout {
    /// 29 words: every field in its own words (the general layout; f32 or f64).
    #[default]
    Full,
    /// 20 words: scenes whose materials are all fluids (F in one word, no plastic word).
    Fluid,
    /// 25 words: C in 5 (shared-exponent codec), f32 only.
    Compact,
    /// 16 words: `Fluid` and `Compact` together, f32 only.
    CompactFluid,
}

/// The most words a layout has ([`StateLayout::Full`]): the sort's field masks are 32 bits.
pub const MAX_FIELDS: usize = 29;

impl StateLayout {
    /// Every layout, in code order.
    pub const ALL: [StateLayout; 4] = [
        StateLayout::Full,
        StateLayout::Fluid,
        StateLayout::Compact,
        StateLayout::CompactFluid,
    ];

    /// The layout of a backend: `Fluid` when every material is a fluid (and `fluid_state` is on,
    /// `--cuda-options fluid_state`), compact when asked (`[solver] particle_state = "compact"`).
    pub fn choose(all_fluid: bool, compact: bool, fluid_state: bool) -> StateLayout {
        match (all_fluid && fluid_state, compact) {
            (false, false) => StateLayout::Full,
            (true, false) => StateLayout::Fluid,
            (false, true) => StateLayout::Compact,
            (true, true) => StateLayout::CompactFluid,
        }
    }

    /// The value of `RTMPM_STATE_LAYOUT` in the kernels.
    pub fn code(self) -> u32 {
        match self {
            StateLayout::Full => 0,
            StateLayout::Fluid => 1,
            StateLayout::Compact => 2,
            StateLayout::CompactFluid => 3,
        }
    }

    /// A short name (logs, errors).
    pub fn name(self) -> &'static str {
        match self {
            StateLayout::Full => "full",
            StateLayout::Fluid => "fluid",
            StateLayout::Compact => "compact",
            StateLayout::CompactFluid => "compact_fluid",
        }
    }

    /// F is one word (J^(1/3), the diagonal of a fluid's F = J^(1/3) I) and there is no plastic
    /// word.
    pub fn fluid(self) -> bool {
        matches!(self, StateLayout::Fluid | StateLayout::CompactFluid)
    }

    /// C is in the shared-exponent format of [`crate::state::codec`] (f32 only).
    pub fn compact(self) -> bool {
        matches!(self, StateLayout::Compact | StateLayout::CompactFluid)
    }

    /// Words per particle.
    pub fn words(self) -> usize {
        self.id() + 1
    }

    /// Position: 3 f32/f64 words.
    pub fn x(self) -> usize {
        0
    }

    /// Velocity: [`Self::v_words`] words from here.
    pub fn v(self) -> usize {
        3
    }

    /// Words of the velocity: 3 reals in every layout.
    pub fn v_words(self) -> usize {
        3
    }

    /// APIC C: [`Self::c_words`] words from here (9 reals column-major, or 5 codec words).
    pub fn c(self) -> usize {
        self.v() + self.v_words()
    }

    /// Words of C.
    pub fn c_words(self) -> usize {
        if self.compact() { 5 } else { 9 }
    }

    /// Deformation gradient: [`Self::f_words`] words from here (9 reals column-major, or the one
    /// word J^(1/3) of a fluid layout).
    pub fn f(self) -> usize {
        self.c() + self.c_words()
    }

    /// Words of F.
    pub fn f_words(self) -> usize {
        if self.fluid() { 1 } else { 9 }
    }

    /// The plastic scalar's word (none in a fluid layout).
    pub fn plastic(self) -> Option<usize> {
        (!self.fluid()).then(|| self.f() + self.f_words())
    }

    /// Mass.
    pub fn mass(self) -> usize {
        self.f() + self.f_words() + usize::from(!self.fluid())
    }

    /// Initial volume.
    pub fn vol0(self) -> usize {
        self.mass() + 1
    }

    /// Material id (integer bits in the low 32 bits of the word).
    pub fn material(self) -> usize {
        self.mass() + 2
    }

    /// Original particle index (integer bits).
    pub fn id(self) -> usize {
        self.mass() + 3
    }

    /// Every word of the layout (bit w: word w).
    pub fn all_words(self) -> u32 {
        ((1u64 << self.words()) - 1) as u32
    }

    /// The preprocessor definitions of the layout: `RTMPM_NFIELDS`, the field offsets `F_*`
    /// (`F_PLASTIC` is -1 without a plastic word), `RTMPM_STATE_FLUID` (F in one word) and
    /// `RTMPM_STATE_COMPACT` (v and C in codec words), each 0 or 1.
    pub fn defines(self) -> Vec<(&'static str, i64)> {
        vec![
            ("RTMPM_NFIELDS", self.words() as i64),
            ("F_X", self.x() as i64),
            ("F_V", self.v() as i64),
            ("F_C", self.c() as i64),
            ("F_F", self.f() as i64),
            ("F_PLASTIC", self.plastic().map_or(-1, |p| p as i64)),
            ("F_MASS", self.mass() as i64),
            ("F_VOL0", self.vol0() as i64),
            ("F_MAT", self.material() as i64),
            ("F_ID", self.id() as i64),
            ("RTMPM_STATE_FLUID", i64::from(self.fluid())),
            ("RTMPM_STATE_COMPACT", i64::from(self.compact())),
        ]
    }

    /// The prelude's text: the definitions of every layout, selected by `RTMPM_STATE_LAYOUT`
    /// (default 0, [`StateLayout::Full`]).
    pub fn prelude() -> String {
        let mut s = String::from(
            "// The particle state's layout (src/contract/state_layout.rs), by RTMPM_STATE_LAYOUT.\n\
             #ifndef RTMPM_STATE_LAYOUT\n#define RTMPM_STATE_LAYOUT 0\n#endif\n",
        );
        for (k, l) in StateLayout::ALL.iter().enumerate() {
            let kw = if k == 0 { "#if" } else { "#elif" };
            s.push_str(&format!(
                "{kw} RTMPM_STATE_LAYOUT == {}  // {}\n",
                l.code(),
                l.name()
            ));
            for (n, v) in l.defines() {
                s.push_str(&format!("#define {n} {v}\n"));
            }
        }
        s.push_str("#else\n#error \"unknown RTMPM_STATE_LAYOUT\"\n#endif\n");
        s.push_str(
            "#if RTMPM_STATE_COMPACT && defined(RTMPM_F64)\n\
             #error \"the compact particle state is single precision only\"\n#endif\n",
        );
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layouts_have_the_documented_words() {
        use StateLayout::*;
        assert_eq!(Full.words(), MAX_FIELDS);
        assert_eq!(Fluid.words(), 20);
        assert_eq!(Compact.words(), 25);
        assert_eq!(CompactFluid.words(), 16);
        // Today's 29-word offsets.
        assert_eq!(
            (Full.x(), Full.v(), Full.c(), Full.f(), Full.plastic()),
            (0, 3, 6, 15, Some(24))
        );
        assert_eq!(
            (Full.mass(), Full.vol0(), Full.material(), Full.id()),
            (25, 26, 27, 28)
        );
        assert_eq!(
            (Fluid.f(), Fluid.plastic(), Fluid.mass(), Fluid.id()),
            (15, None, 16, 19)
        );
        assert_eq!(
            (Compact.v(), Compact.c(), Compact.f(), Compact.plastic()),
            (3, 6, 11, Some(20))
        );
        assert_eq!((CompactFluid.f(), CompactFluid.mass()), (11, 12));
        for l in StateLayout::ALL {
            // Every word belongs to exactly one field.
            let mut owner = vec![0; l.words()];
            let mut mark = |from: usize, n: usize| {
                for o in owner.iter_mut().skip(from).take(n) {
                    *o += 1;
                }
            };
            mark(l.x(), 3);
            mark(l.v(), l.v_words());
            mark(l.c(), l.c_words());
            mark(l.f(), l.f_words());
            if let Some(p) = l.plastic() {
                mark(p, 1);
            }
            for w in [l.mass(), l.vol0(), l.material(), l.id()] {
                mark(w, 1);
            }
            assert!(owner.iter().all(|&o| o == 1), "{l:?}: {owner:?}");
            assert_eq!(l.all_words().count_ones() as usize, l.words());
            assert_eq!(StateLayout::ALL[l.code() as usize], l);
        }
        assert_eq!(StateLayout::choose(false, false, true), Full);
        assert_eq!(StateLayout::choose(true, false, true), Fluid);
        assert_eq!(StateLayout::choose(true, false, false), Full);
        assert_eq!(StateLayout::choose(true, true, true), CompactFluid);
        assert_eq!(StateLayout::choose(false, true, true), Compact);
    }

    #[test]
    fn prelude_defines_every_layout() {
        let p = StateLayout::prelude();
        assert!(p.contains("#if RTMPM_STATE_LAYOUT == 0  // full\n#define RTMPM_NFIELDS 29\n"));
        assert!(p.contains("#elif RTMPM_STATE_LAYOUT == 1  // fluid\n#define RTMPM_NFIELDS 20\n"));
        assert!(p.contains("#define F_PLASTIC -1\n"));
        assert_eq!(p.matches("#define F_ID ").count(), 4);
    }
}

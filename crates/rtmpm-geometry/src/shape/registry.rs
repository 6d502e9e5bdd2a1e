//! The registry of the shapes: `shapes!`, invoked with the one list of shapes in
//! `shape/mod.rs`, gives the [`Shape`] enum and its dispatch, the scene's `shape = "..."`
//! names, the uses each allows and the GPU kind codes.

use super::Shape;
use super::kind::ShapeInfo;
use glam::Vec3;

/// The registry: the enum of shapes and its dispatch, from one list of `Variant(Type)`; the
/// position in the list is the shape's kind code on the GPU.
macro_rules! shapes {
    ($($variant:ident($ty:ty)),* $(,)?) => {
        /// A shape: what a collider, a body, an emitter or a rigid body is (see the module
        /// documentation of [`crate::shape`]).
        #[derive(Clone, Debug, PartialEq)]
        pub enum Shape {
            $(#[doc = concat!("[`", stringify!($ty), "`]")] $variant($ty)),*
        }

        impl Shape {
            /// Every shape, in kind-code order.
            pub const ALL: &'static [ShapeInfo] = &[$(ShapeInfo {
                name: <$ty>::NAME,
                noun: <$ty>::NOUN,
                fields: <$ty>::FIELDS,
                uses: <$ty>::USES,
                refusal: <$ty>::REFUSAL,
                device: <$ty>::DEVICE,
            }),*];

            /// The names of [`Shape::ALL`], in order.
            pub const NAMES: &'static [&'static str] = &[$(<$ty>::NAME),*];

            /// Read shape `kind` (its index in [`Shape::ALL`]) from a table of use `u`.
            pub fn read<F: ShapeFields>(kind: usize, f: &F, u: Use) -> Result<Shape, F::Error> {
                let name = Self::NAMES.get(kind).copied().unwrap_or_default();
                $(if name == <$ty>::NAME {
                    return <$ty>::read(f, u).map(Shape::$variant);
                })*
                Err(f.error("shape", format!("no shape of code {kind}"), "name a shape".into()))
            }

            /// Read shape `kind` as a rigid body: the shape in the body frame, the centre in
            /// the world and the rest orientation ([`ShapeKind::read_body`]).
            pub fn read_body<F: ShapeFields>(
                kind: usize,
                f: &F,
            ) -> Result<(Shape, Vec3, Quat), F::Error> {
                let name = Self::NAMES.get(kind).copied().unwrap_or_default();
                $(if name == <$ty>::NAME {
                    return <$ty>::read_body(f).map(|(s, c, q)| (Shape::$variant(s), c, q));
                })*
                Err(f.error("shape", format!("no shape of code {kind}"), "name a shape".into()))
            }

            /// Name of the shape, as written in scene files.
            pub fn name(&self) -> &'static str {
                match self { $(Shape::$variant(_) => <$ty>::NAME),* }
            }

            /// See [`ShapeKind::body_frame`].
            pub fn body_frame(self) -> (Shape, Vec3, Quat) {
                match self {
                    $(Shape::$variant(s) => {
                        let (s, c, q) = s.body_frame();
                        (Shape::$variant(s), c, q)
                    }),*
                }
            }

            /// See [`ShapeKind::distance`].
            pub fn distance(&self, x: Vec3) -> f32 {
                match self { $(Shape::$variant(s) => s.distance(x)),* }
            }

            /// See [`ShapeKind::normal`].
            pub fn normal(&self, x: Vec3) -> Vec3 {
                match self { $(Shape::$variant(s) => s.normal(x)),* }
            }

            /// See [`ShapeKind::contains`].
            pub fn contains(&self, x: Vec3) -> bool {
                match self { $(Shape::$variant(s) => s.contains(x)),* }
            }

            /// See [`ShapeKind::bounds`].
            pub fn bounds(&self) -> (Vec3, Vec3) {
                match self { $(Shape::$variant(s) => s.bounds()),* }
            }

            /// See [`ShapeKind::distance_bounds`].
            pub fn distance_bounds(&self) -> (Vec3, Vec3) {
                match self { $(Shape::$variant(s) => s.distance_bounds()),* }
            }

            /// See [`ShapeKind::center`].
            pub fn center(&self) -> Vec3 {
                match self { $(Shape::$variant(s) => s.center()),* }
            }

            /// See [`ShapeKind::volume`].
            pub fn volume(&self) -> f32 {
                match self { $(Shape::$variant(s) => s.volume()),* }
            }

            /// See [`ShapeKind::area`].
            pub fn area(&self) -> f32 {
                match self { $(Shape::$variant(s) => s.area()),* }
            }

            /// See [`ShapeKind::half_extents`].
            pub fn half_extents(&self, r: Mat3) -> Vec3 {
                match self { $(Shape::$variant(s) => s.half_extents(r)),* }
            }

            /// See [`ShapeKind::bounding_radius`].
            pub fn bounding_radius(&self) -> f32 {
                match self { $(Shape::$variant(s) => s.bounding_radius()),* }
            }

            /// See [`ShapeKind::gpu`].
            pub fn gpu(&self) -> GpuParams<'_> {
                match self { $(Shape::$variant(s) => s.gpu()),* }
            }

            /// See [`ShapeKind::usd`].
            pub fn usd(&self) -> Option<UsdPrim<'_>> {
                match self { $(Shape::$variant(s) => s.usd()),* }
            }
        }
    };
}

impl Shape {
    /// Kind code on the GPU: the position in [`Shape::ALL`].
    pub fn code(&self) -> u32 {
        Self::code_of(self.name()).unwrap_or(0)
    }

    /// The kind code of the shape named `name`.
    pub fn code_of(name: &str) -> Option<u32> {
        Self::NAMES
            .iter()
            .position(|n| *n == name)
            .map(|k| k as u32)
    }

    /// What the registry knows of this shape.
    pub fn info(&self) -> &'static ShapeInfo {
        &Self::ALL[self.code() as usize]
    }

    /// The distance's bounds, `None` when they are not finite (a half-space).
    pub fn finite_bounds(&self) -> Option<(Vec3, Vec3)> {
        let (lo, hi) = self.distance_bounds();
        (lo.is_finite() && hi.is_finite()).then_some((lo, hi))
    }
}

use super::*;

fn close(a: f32, b: f32) -> bool {
    (a - b).abs() < 1e-5
}
fn vclose(a: Vec3, b: Vec3) -> bool {
    (a - b).length() < 1e-5
}

fn cylinder(center: Vec3, axis: Vec3, radius: f32, half_height: f32) -> Shape {
    Shape::Cylinder(Cylinder {
        center,
        axis,
        radius,
        half_height,
    })
}

#[test]
fn half_space() {
    let s = Shape::HalfSpace(HalfSpace {
        point: Vec3::new(0.0, 1.0, 0.0),
        normal: Vec3::Y,
    });
    assert!(close(s.distance(Vec3::new(5.0, 3.0, 2.0)), 2.0));
    assert!(close(s.distance(Vec3::new(5.0, 0.5, 2.0)), -0.5));
    assert!(close(s.distance(Vec3::new(0.0, 1.0, 0.0)), 0.0));
    assert_eq!(s.normal(Vec3::ZERO), Vec3::Y);
    assert!(vclose(s.center(), Vec3::Y));
    assert!(s.finite_bounds().is_none());
}

#[test]
fn sphere() {
    let s = Shape::Sphere(Sphere {
        center: Vec3::ONE,
        radius: 0.5,
    });
    assert!(close(s.distance(Vec3::ONE), -0.5));
    assert!(close(s.distance(Vec3::new(2.0, 1.0, 1.0)), 0.5));
    assert!(close(s.distance(Vec3::new(1.0, 1.5, 1.0)), 0.0));
    assert!(vclose(s.normal(Vec3::new(1.0, 0.0, 1.0)), -Vec3::Y));
    assert!(vclose(s.normal(Vec3::new(1.2, 1.0, 1.0)), Vec3::X));
    assert!(s.contains(Vec3::new(1.0, 1.5, 1.0)));
    assert!(!s.contains(Vec3::new(1.0, 1.51, 1.0)));
}

#[test]
fn boxes() {
    let s = Shape::Box(Cuboid::centred(Vec3::ZERO, Vec3::new(1.0, 2.0, 3.0)));
    assert!(close(s.distance(Vec3::ZERO), -1.0));
    assert!(close(s.distance(Vec3::new(0.0, 1.5, 0.0)), -0.5));
    assert!(close(s.distance(Vec3::new(2.0, 0.0, 0.0)), 1.0));
    assert!(close(s.distance(Vec3::new(1.0, 0.0, 0.0)), 0.0));
    // Corner region: Euclidean distance to the corner.
    assert!(close(s.distance(Vec3::new(4.0, 6.0, 0.0)), 5.0));
    assert!(vclose(s.normal(Vec3::new(2.0, 0.0, 0.0)), Vec3::X));
    assert!(vclose(s.normal(Vec3::new(0.0, -1.9, 0.0)), -Vec3::Y));
    assert!(vclose(s.normal(Vec3::new(0.0, 0.0, 2.9)), Vec3::Z));
    let n = s.normal(Vec3::new(4.0, 6.0, 0.0));
    assert!(vclose(n, Vec3::new(3.0, 4.0, 0.0) / 5.0));
    // The surface is inside for the sampler.
    assert!(s.contains(Vec3::new(1.0, 2.0, 3.0)));
    assert!(!s.contains(Vec3::new(1.0, 2.0, 3.0001)));
}

#[test]
fn cylinders() {
    let s = cylinder(Vec3::ZERO, Vec3::Z, 1.0, 2.0);
    assert!(close(s.distance(Vec3::ZERO), -1.0));
    assert!(close(s.distance(Vec3::new(0.0, 0.0, 1.8)), -0.2));
    assert!(close(s.distance(Vec3::new(3.0, 0.0, 0.0)), 2.0));
    assert!(close(s.distance(Vec3::new(0.0, 0.0, 3.0)), 1.0));
    assert!(close(s.distance(Vec3::new(0.0, 1.0, 0.0)), 0.0));
    assert!(close(s.distance(Vec3::new(4.0, 0.0, 6.0)), 5.0));
    assert!(vclose(s.normal(Vec3::new(0.0, 2.0, 0.0)), Vec3::Y));
    assert!(vclose(s.normal(Vec3::new(0.0, 0.5, -1.9)), -Vec3::Z));
    assert!(vclose(s.normal(Vec3::new(0.9, 0.0, 0.0)), Vec3::X));
    assert!(vclose(
        s.normal(Vec3::new(4.0, 0.0, 6.0)),
        Vec3::new(3.0, 0.0, 4.0) / 5.0
    ));
}

#[test]
fn bounds_contain_the_shape() {
    let shapes = [
        Shape::Sphere(Sphere {
            center: Vec3::ONE,
            radius: 0.5,
        }),
        Shape::Box(Cuboid::centred(Vec3::ZERO, Vec3::new(1.0, 2.0, 3.0))),
        cylinder(
            Vec3::new(0.2, 0.0, 0.0),
            Vec3::new(1.0, 2.0, 0.5).normalize(),
            0.3,
            0.8,
        ),
    ];
    for s in &shapes {
        let (lo, hi) = s.bounds();
        // Points just outside every face of the bounds are outside the shape, and the bounds
        // are tight: some point on each face is within 1e-3 of the surface.
        for axis in 0..3 {
            for (side, face) in [(-1.0f32, lo[axis]), (1.0, hi[axis])] {
                let mut best = f32::INFINITY;
                for i in 0..=40 {
                    for j in 0..=40 {
                        let mut p = lo + (hi - lo) * 0.5;
                        let (a1, a2) = ((axis + 1) % 3, (axis + 2) % 3);
                        p[a1] = lo[a1] + (hi[a1] - lo[a1]) * i as f32 / 40.0;
                        p[a2] = lo[a2] + (hi[a2] - lo[a2]) * j as f32 / 40.0;
                        p[axis] = face + side * 1e-4;
                        assert!(s.distance(p) > 0.0, "{s:?} {p}");
                        best = best.min(s.distance(p));
                    }
                }
                assert!(best < 0.02, "{s:?} axis {axis}: {best}");
            }
        }
    }
}

/// A rigid body's frame: about the centre, the box's half-extents and the cylinder's axis
/// turned to y, bit for bit the values the scene's min/max and centre give.
#[test]
fn a_rigid_body_frame_is_exactly_about_the_centre() {
    let (min, max) = (Vec3::new(0.1, 0.23, -0.7), Vec3::new(0.37, 0.9, -0.11));
    let (body, at, q) = Shape::Box(Cuboid { min, max }).body_frame();
    let h = 0.5 * (max - min);
    assert_eq!(at, 0.5 * (min + max));
    assert_eq!(q, Quat::IDENTITY);
    let Shape::Box(b) = &body else {
        panic!("a box");
    };
    assert_eq!(b.half_size(), h);
    assert_eq!(b.middle(), Vec3::ZERO);
    assert_eq!(
        body.volume().to_bits(),
        (8.0 * h.x * h.y * h.z).to_bits(),
        "the volume of 8 h_x h_y h_z"
    );
    let p = Vec3::new(0.05, -0.31, 0.2);
    assert_eq!(body.distance(p), box_distance(p, Vec3::ZERO, h));

    let axis = Vec3::new(0.48, 0.6, 0.64);
    let c = cylinder(Vec3::new(0.5, 0.4, 0.3), axis, 0.1, 0.2);
    let (body, at, q) = c.body_frame();
    assert_eq!(at, Vec3::new(0.5, 0.4, 0.3));
    assert!((q * Vec3::Y - axis).length() < 1e-6);
    let r = Mat3::from_quat(q);
    // The turned bound of a body-frame cylinder is the one of its turned axis r * y.
    let a = r.y_axis;
    let a2 = a * a;
    let disc = Vec3::new(a2.y + a2.z, a2.x + a2.z, a2.x + a2.y);
    let expect = a.abs() * 0.2 + Vec3::new(disc.x.sqrt(), disc.y.sqrt(), disc.z.sqrt()) * 0.1;
    assert_eq!(body.half_extents(r), expect);
}

#[test]
fn the_registry_lists_every_shape_once_with_its_uses() {
    assert_eq!(
        Shape::NAMES,
        &[
            "half_space",
            "box",
            "sphere",
            "cylinder",
            "mesh",
            "particles"
        ]
    );
    for (k, s) in Shape::ALL.iter().enumerate() {
        assert_eq!(Shape::code_of(s.name), Some(k as u32));
        assert!(!s.uses.is_empty(), "{}", s.name);
    }
    let b = Shape::Box(Cuboid::centred(Vec3::ZERO, Vec3::ONE));
    assert_eq!(b.code(), 1);
    assert_eq!(b.info().name, "box");
    // Only the particles have no device twin.
    let device: Vec<&str> = Shape::ALL
        .iter()
        .filter(|s| s.device)
        .map(|s| s.name)
        .collect();
    assert_eq!(device, ["half_space", "box", "sphere", "cylinder", "mesh"]);
}

#[test]
fn a_use_a_shape_does_not_allow_is_refused_with_the_shapes_it_allows() {
    let info = |n: &str| Shape::ALL.iter().find(|s| s.name == n).expect("a shape");
    assert_eq!(
        info("mesh").refused(Use::Emitter).as_deref(),
        Some("an emitter cannot be a mesh")
    );
    assert_eq!(
        info("half_space").refused(Use::RigidBody).as_deref(),
        Some("a rigid body cannot be a half-space (it is infinite)")
    );
    assert_eq!(
        info("particles").refused(Use::Collider).as_deref(),
        Some(
            "a collider cannot be a particle file (only a body can be made of a file's particles)"
        )
    );
    assert_eq!(info("mesh").refused(Use::RigidBody), None);
    assert_eq!(
        allowed_for(Use::Emitter),
        "\"box\" (min, max), \"sphere\" (center, radius) or \"cylinder\" (center, axis, radius, height)"
    );
    assert_eq!(
        allowed_for(Use::Body),
        "\"box\" (min, max), \"sphere\" (center, radius), \"cylinder\" (center, axis, radius, \
         height), \"mesh\" (file, scale, translate) or \"particles\" (file, scale, translate)"
    );
    for u in Use::ALL {
        assert!(Shape::ALL.iter().any(|s| s.allows(u)), "{u:?}");
    }
}

#[test]
fn gpu_parameters_are_the_fields_in_order() {
    let c = cylinder(Vec3::new(1.0, 2.0, 3.0), Vec3::Y, 0.5, 0.25);
    assert_eq!(c.gpu().p, [1.0, 2.0, 3.0, 0.0, 1.0, 0.0, 0.5, 0.25]);
    let b = Shape::Box(Cuboid {
        min: Vec3::new(-1.0, -2.0, -3.0),
        max: Vec3::new(4.0, 5.0, 6.0),
    });
    assert_eq!(b.gpu().p, [-1.0, -2.0, -3.0, 4.0, 5.0, 6.0, 0.0, 0.0]);
    assert!(b.gpu().values.is_empty());
}

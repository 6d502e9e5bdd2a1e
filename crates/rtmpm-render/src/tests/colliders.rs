//! Image-content tests of the renderer: colliders and rigid bodies.

use super::*;

fn collider(shape: rtmpm_geometry::Shape, velocity: Vec3) -> rtmpm_geometry::Collider {
    rtmpm_geometry::Collider {
        pivot: shape.center(),
        shape,
        rule: Default::default(),
        velocity,
        angular_velocity: Vec3::ZERO,
        keyframes: None,
    }
}

/// Neutral grey, lit: the colour of collider surfaces.
fn is_collider_grey(p: [u8; 3]) -> bool {
    let (lo, hi) = (*p.iter().min().unwrap(), *p.iter().max().unwrap());
    hi - lo <= 6 && lo >= 40
}

#[test]
fn colliders_are_drawn_hide_particles_and_can_be_hidden() {
    use rtmpm_geometry::Shape;
    // Front camera at z = 3 looking at the origin (160x90, fov 40: 1 m at the origin is ~41
    // pixels). A sphere collider right of the centre with blue particles behind it, a red
    // cube left of the centre in front of a box collider, and a half-space floor (y < -0.5),
    // clipped to the scene box [-1, 1]^3.
    let mut pos = cube(Vec3::new(0.55, 0.0, -0.7), 0.2, 6);
    let blue = pos.len();
    pos.extend(cube(Vec3::new(-0.55, 0.0, 0.6), 0.2, 6));
    let mat: Vec<u32> = (0..pos.len())
        .map(|i| if i < blue { 0 } else { 2 })
        .collect();
    let mut o = opts(160, 90);
    o.floor = None;
    o.colliders = vec![
        collider(
            Shape::Sphere(rtmpm_geometry::shape::Sphere {
                center: Vec3::new(0.55, 0.0, 0.0),
                radius: 0.3,
            }),
            Vec3::ZERO,
        ),
        collider(
            Shape::Box(rtmpm_geometry::shape::Cuboid::centred(
                Vec3::new(-0.55, 0.0, -0.2),
                Vec3::splat(0.3),
            )),
            Vec3::ZERO,
        ),
        collider(
            Shape::HalfSpace(rtmpm_geometry::shape::HalfSpace {
                point: Vec3::new(0.0, -0.5, 0.0),
                normal: Vec3::Y,
            }),
            Vec3::ZERO,
        ),
    ];
    let input = RenderInput {
        positions: &pos,
        material: &mat,
        field: None,
        surface: None,
    };
    let with = render(&input, &o).unwrap();
    let colliders = std::mem::take(&mut o.colliders);
    let without = render(&input, &o).unwrap();
    dump(&with, "colliders_on");
    dump(&without, "colliders_off");
    let v = o_view(160, 90);
    let px = |p: Vec3| {
        let (x, y, _) = v.project(p);
        (x as u32, y as u32)
    };
    // Sphere: grey where it is, hiding the blue particles behind it; blue without colliders.
    let (x, y) = px(Vec3::new(0.55, 0.0, -0.7));
    assert!(is_collider_grey(with.pixel(x, y)), "{:?}", with.pixel(x, y));
    assert_eq!(
        dominant(without.pixel(x, y)),
        Some(2),
        "{:?}",
        without.pixel(x, y)
    );
    // Box: grey beside the red cube, which stays in front of it.
    let (x, y) = px(Vec3::new(-0.55, 0.22, 0.1));
    assert!(is_collider_grey(with.pixel(x, y)), "{:?}", with.pixel(x, y));
    assert!(
        !is_collider_grey(without.pixel(x, y)),
        "{:?}",
        without.pixel(x, y)
    );
    let (x, y) = px(Vec3::new(-0.55, 0.0, 0.7));
    assert_eq!(
        dominant(with.pixel(x, y)),
        Some(0),
        "{:?}",
        with.pixel(x, y)
    );
    // The floor slab's front face (z = 1, y in [-1, -0.5], partly in view) is grey; the sky above the scene
    // box and the centre between the shapes are not (the half-space is clipped).
    let (x, y) = px(Vec3::new(0.0, -0.62, 1.0));
    assert!(is_collider_grey(with.pixel(x, y)), "{:?}", with.pixel(x, y));
    assert!(
        !is_collider_grey(without.pixel(x, y)),
        "{:?}",
        without.pixel(x, y)
    );
    for (x, y) in [(80, 2), (80, 45), (2, 2)] {
        assert!(
            !is_collider_grey(with.pixel(x, y)),
            "{x},{y}: {:?}",
            with.pixel(x, y)
        );
    }
    // The sphere shades from lit to dark across its surface (light from above-left).
    let (xs, ys) = px(Vec3::new(0.55, 0.0, 0.3));
    let top = with.pixel(xs - 4, ys - 8)[0] as i32;
    let bottom = with.pixel(xs + 4, ys + 8)[0] as i32;
    assert!(top > bottom + 20, "{top} vs {bottom}");

    // A moving sphere is drawn where it is at the frame's time.
    o.colliders = vec![collider(
        Shape::Sphere(rtmpm_geometry::shape::Sphere {
            center: Vec3::new(-0.5, 0.0, 0.0),
            radius: 0.2,
        }),
        Vec3::new(1.0, 0.0, 0.0),
    )];
    o.time = 1.0;
    let moved = render(&input, &o).unwrap();
    let (x, y) = px(Vec3::new(0.5, 0.0, 0.2));
    assert!(
        is_collider_grey(moved.pixel(x, y)),
        "{:?}",
        moved.pixel(x, y)
    );
    let (x, y) = px(Vec3::new(-0.5, 0.0, 0.2));
    assert!(
        !is_collider_grey(moved.pixel(x, y)),
        "{:?}",
        moved.pixel(x, y)
    );
    drop(colliders);
}

#[test]
fn colliders_cast_shadows() {
    use rtmpm_geometry::Shape;
    // A sphere collider above the ground, seen from above: it darkens the ground (no particles).
    let pos = [Vec3::new(0.9, -0.75, 0.9)];
    let mat = [4u32];
    let mut o = RenderOptions::new(Vec3::new(-1.0, -0.8, -1.0), Vec3::new(1.0, 1.0, 1.0), 0.01);
    o.width = 160;
    o.height = 90;
    o.camera = Camera {
        position: Vec3::new(0.0, 3.0, 0.01),
        target: Vec3::new(0.0, -0.8, 0.0),
        fov_deg: 60.0,
    };
    o.colliders = vec![collider(
        Shape::Sphere(rtmpm_geometry::shape::Sphere {
            center: Vec3::ZERO,
            radius: 0.25,
        }),
        Vec3::ZERO,
    )];
    let input = RenderInput {
        positions: &pos,
        material: &mat,
        field: None,
        surface: None,
    };
    let lit = render(&input, &o).unwrap();
    o.shadows = false;
    let unlit = render(&input, &o).unwrap();
    dump(&lit, "collider_shadow");
    // The light comes from (-0.45, 1, 0.55): the sphere's shadow on the ground (y = -0.8) is
    // centred 0.8 x (0.45, -0.55) away from under it, clear of the sphere seen from above.
    let v = o.camera.view(160, 90);
    let (x, y, _) = v.project(Vec3::new(0.36, -0.8, -0.44));
    let (x, y) = (x as u32, y as u32);
    let (dark, bright) = (lit.pixel(x, y), unlit.pixel(x, y));
    assert!(
        dark[0] as i32 + 15 < bright[0] as i32,
        "{dark:?} vs {bright:?}"
    );
    // Beside the shadow the ground is lit the same either way.
    let (x, y, _) = v.project(Vec3::new(-0.6, -0.8, 0.5));
    let (x, y) = (x as u32, y as u32);
    assert_eq!(lit.pixel(x, y), unlit.pixel(x, y));
}

#[test]
fn a_rigid_body_is_drawn_at_its_pose() {
    use rtmpm_geometry::Shape;
    use rtmpm_rigid::BodyState;
    // A thin bar (long along its own x) turned 90 degrees about z stands upright at x = 0.5,
    // in front of blue particles: grey along its upright length, and not grey where the unturned
    // bar reaches (x = 0.75).
    let pos = cube(Vec3::new(0.55, 0.0, -0.7), 0.45, 8);
    let mat = vec![0u32; pos.len()];
    let body = BodyState {
        shape: Shape::Box(rtmpm_geometry::shape::Cuboid::centred(
            glam::Vec3::ZERO,
            Vec3::new(0.3, 0.05, 0.05),
        )),
        rotation: glam::Mat3::from_rotation_z(std::f32::consts::FRAC_PI_2),
        center: Vec3::new(0.5, 0.0, 0.0),
        velocity: Vec3::ZERO,
        angular_velocity: Vec3::ZERO,
        dynamic: true,
        condition: rtmpm_physics::boundary::Condition::Slip,
        friction: 0.5,
    };
    let mut o = opts(160, 90);
    o.floor = None;
    o.colliders = vec![body.collider()];
    let input = RenderInput {
        positions: &pos,
        material: &mat,
        field: None,
        surface: None,
    };
    let img = render(&input, &o).unwrap();
    let v = o_view(160, 90);
    let px = |p: Vec3| {
        let (x, y, _) = v.project(p);
        (x as u32, y as u32)
    };
    let (x, y) = px(Vec3::new(0.5, 0.2, 0.05));
    assert!(is_collider_grey(img.pixel(x, y)), "{:?}", img.pixel(x, y));
    let (x, y) = px(Vec3::new(0.75, 0.0, 0.05));
    assert!(!is_collider_grey(img.pixel(x, y)), "{:?}", img.pixel(x, y));
    // The same bar unturned covers that point.
    let unturned = BodyState {
        rotation: glam::Mat3::IDENTITY,
        ..body
    };
    o.colliders = vec![unturned.collider()];
    let img = render(&input, &o).unwrap();
    assert!(is_collider_grey(img.pixel(x, y)), "{:?}", img.pixel(x, y));
}

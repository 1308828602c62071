//! Offscreen rendering on whatever adapter exists (in CI: Mesa lavapipe with
//! `VK_DRIVER_FILES=/usr/share/vulkan/icd.d/lvp_icd.x86_64.json WGPU_BACKEND=vulkan`).
//!
//! Pixel checks with stated tolerances, never byte-exact images: the brain is
//! pink where it is, each spatula is grey where it is, a colour field changes
//! the brain's colours, overlays show their colours. Skips with a message only
//! when there is no adapter at all; any other error fails. PNGs are written to
//! the temp dir (`render_*.png`) for a human to look at.

use fissure::geometry::{Pose, SpatulaShape};
use fissure::math::{Quat, Vec3};
use fissure::render::capture::{read_offscreen, save_png};
use fissure::render::{
    ColorMap, FieldKind, OrbitCamera, Overlays, PairSegment, RenderError, Renderer, ScalarField,
    SceneView, SkullSphere, SpatulaView,
};
use image::RgbaImage;

const SIZE: (u32, u32) = (320, 240);
/// A pixel differs from the background when any channel differs by more than this (0..255).
const BACKGROUND_TOLERANCE: i32 = 24;

/// A brain-sized ellipsoid (semi-axes 70 x 85 x 60 mm) from a subdivided icosahedron.
fn ellipsoid(subdivisions: u32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let mut p: Vec<Vec3> = [
        [-1.0, t, 0.0],
        [1.0, t, 0.0],
        [-1.0, -t, 0.0],
        [1.0, -t, 0.0],
        [0.0, -1.0, t],
        [0.0, 1.0, t],
        [0.0, -1.0, -t],
        [0.0, 1.0, -t],
        [t, 0.0, -1.0],
        [t, 0.0, 1.0],
        [-t, 0.0, -1.0],
        [-t, 0.0, 1.0],
    ]
    .iter()
    .map(|v| Vec3::from(*v).normalize())
    .collect();
    let mut tris: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..subdivisions {
        let mut mid = std::collections::BTreeMap::new();
        let mut next = Vec::with_capacity(tris.len() * 4);
        let mut midpoint = |a: u32, b: u32, p: &mut Vec<Vec3>| {
            *mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
                p.push(((p[a as usize] + p[b as usize]) * 0.5).normalize());
                (p.len() - 1) as u32
            })
        };
        for [a, b, c] in tris {
            let (ab, bc, ca) = (
                midpoint(a, b, &mut p),
                midpoint(b, c, &mut p),
                midpoint(c, a, &mut p),
            );
            next.extend_from_slice(&[[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        tris = next;
    }
    let scale = Vec3::new(0.070, 0.085, 0.060);
    (p.iter().map(|v| v.component_mul(&scale)).collect(), tris)
}

fn spatulas() -> [SpatulaView; 2] {
    let shape = SpatulaShape {
        length: 0.06,
        width: 0.012,
        thickness: 0.0015,
    };
    // Blades along +y (rotation 90 deg about z), faces up, above the front of the brain.
    let along_y = Quat::from_axis_angle(&Vec3::z_axis(), std::f64::consts::FRAC_PI_2);
    [
        SpatulaView::new(
            shape,
            Pose {
                position: Vec3::new(-0.03, -0.10, 0.07),
                rotation: along_y,
            },
        ),
        SpatulaView::new(
            shape,
            Pose {
                position: Vec3::new(0.03, -0.10, 0.07),
                rotation: along_y,
            },
        ),
    ]
}

fn camera() -> OrbitCamera {
    OrbitCamera::framing(Vec3::new(-0.07, -0.10, -0.06), Vec3::new(0.07, 0.085, 0.08))
}

/// Pixel (x, y) of a world point for the test camera.
fn pixel_of(camera: &OrbitCamera, p: Vec3) -> (u32, u32) {
    let m = camera.view_projection(SIZE.0 as f64 / SIZE.1 as f64);
    let h = m * (p - camera.target).push(1.0);
    let ndc = h.xyz() / h.w;
    let x = ((ndc.x + 1.0) * 0.5 * SIZE.0 as f64)
        .floor()
        .clamp(0.0, SIZE.0 as f64 - 1.0);
    let y = ((1.0 - ndc.y) * 0.5 * SIZE.1 as f64)
        .floor()
        .clamp(0.0, SIZE.1 as f64 - 1.0);
    (x as u32, y as u32)
}

fn rgb(img: &RgbaImage, (x, y): (u32, u32)) -> [i32; 3] {
    let p = img.get_pixel(x, y).0;
    [p[0] as i32, p[1] as i32, p[2] as i32]
}

fn differs(a: [i32; 3], b: [i32; 3], tolerance: i32) -> bool {
    (0..3).any(|k| (a[k] - b[k]).abs() > tolerance)
}

/// True when some pixel within `radius` of `px` satisfies `want` (lines are
/// one pixel wide and MSAA blends their edges).
fn any_near(
    img: &RgbaImage,
    (x, y): (u32, u32),
    radius: i64,
    want: impl Fn([i32; 3]) -> bool,
) -> bool {
    (-radius..=radius).any(|dy| {
        (-radius..=radius).any(|dx| {
            let (px, py) = (x as i64 + dx, y as i64 + dy);
            px >= 0
                && py >= 0
                && px < SIZE.0 as i64
                && py < SIZE.1 as i64
                && want(rgb(img, (px as u32, py as u32)))
        })
    })
}

/// The point of the test ellipsoid's surface in the direction of `p` from its centre.
fn on_brain(p: Vec3) -> Vec3 {
    let axes = Vec3::new(0.070, 0.085, 0.060);
    p.component_div(&axes).normalize().component_mul(&axes)
}

fn is_pinkish(c: [i32; 3]) -> bool {
    c[0] > 60 && c[0] as f64 > 1.25 * c[1] as f64 && c[0] as f64 > 1.2 * c[2] as f64
}

fn is_greyish(c: [i32; 3]) -> bool {
    let (max, min) = (
        c.iter().max().copied().unwrap_or(0),
        c.iter().min().copied().unwrap_or(0),
    );
    max > 40 && max - min < 40
}

/// The renderer, or `None` (after printing why) when no adapter exists.
fn renderer_or_skip(test: &str) -> Option<Renderer> {
    match Renderer::new_offscreen(SIZE) {
        Ok(r) => {
            println!("{test}: rendering on {}", r.adapter_name());
            Some(r)
        }
        Err(RenderError::NoAdapter(why)) => {
            println!(
                "SKIP {test}: no GPU adapter ({why}); set VK_DRIVER_FILES=/usr/share/vulkan/icd.d/lvp_icd.x86_64.json WGPU_BACKEND=vulkan"
            );
            None
        }
        Err(e) => panic!("{test}: renderer creation failed: {e}"),
    }
}

fn save(img: &RgbaImage, name: &str) {
    let path = std::env::temp_dir().join(name);
    save_png(img, &path).expect("write PNG");
    println!("wrote {}", path.display());
}

#[test]
fn brain_and_both_spatulas_are_visible_and_field_changes_colours() {
    let Some(mut renderer) = renderer_or_skip("brain_and_both_spatulas_are_visible") else {
        return;
    };
    let (positions, triangles) = ellipsoid(3);
    let spatulas = spatulas();
    let cam = camera();
    let mut view = SceneView::new(&positions, &triangles, cam);
    view.spatulas = &spatulas;
    renderer.render_offscreen(&view).expect("render");
    let plain = read_offscreen(&renderer).expect("read back");
    save(&plain, "render_plain.png");
    assert_eq!(plain.dimensions(), SIZE);

    let background = rgb(&plain, (0, 0));
    // The brain: a point on its lower-front-right surface, clear of the spatulas, is pink.
    let brain_px = pixel_of(&cam, on_brain(Vec3::new(0.045, -0.045, -0.015)));
    let c = rgb(&plain, brain_px);
    assert!(
        differs(c, background, BACKGROUND_TOLERANCE),
        "brain pixel {brain_px:?} = {c:?} looks like the background {background:?}"
    );
    assert!(
        is_pinkish(c),
        "brain pixel {brain_px:?} = {c:?} is not brain-pink"
    );
    let pink = plain
        .pixels()
        .filter(|p| is_pinkish([p.0[0] as i32, p.0[1] as i32, p.0[2] as i32]))
        .count();
    assert!(
        pink > (SIZE.0 * SIZE.1 / 10) as usize,
        "only {pink} pink pixels: the brain should fill more than 10% of the frame"
    );

    // Each spatula: the middle of its upper face is grey and not background.
    for (k, s) in spatulas.iter().enumerate() {
        let centre = s.pose.transform_point(&Vec3::new(
            s.shape.length * 0.5,
            0.0,
            s.shape.thickness * 0.5,
        ));
        let px = pixel_of(&cam, centre);
        let c = rgb(&plain, px);
        assert!(
            differs(c, background, BACKGROUND_TOLERANCE),
            "spatula {k} pixel {px:?} = {c:?} looks like the background"
        );
        assert!(
            is_greyish(c),
            "spatula {k} pixel {px:?} = {c:?} is not metallic grey"
        );
    }

    // A displacement field (here: height, mm) recolours the brain.
    let values: Vec<f64> = positions.iter().map(|p| p.z * 1e3).collect();
    view.surface.field = Some(ScalarField {
        values: &values,
        kind: FieldKind::DisplacementMm,
        map: ColorMap::Viridis,
        range: (-60.0, 60.0),
    });
    renderer.render_offscreen(&view).expect("render with field");
    let coloured = read_offscreen(&renderer).expect("read back");
    save(&coloured, "render_field.png");
    let c2 = rgb(&coloured, brain_px);
    assert!(
        differs(c, c2, 30),
        "the field must visibly change the brain's colour at {brain_px:?}: {c:?} -> {c2:?}"
    );
    assert!(!is_pinkish(c2), "viridis is not pink: {c2:?}");
    let top = rgb(
        &coloured,
        pixel_of(&cam, on_brain(Vec3::new(0.0, 0.02, 1.0))),
    );
    assert!(
        differs(top, c2, 30),
        "different heights must get different colours: top {top:?} vs side {c2:?}"
    );
    // The spatulas keep their colour.
    let s = &spatulas[0];
    let px = pixel_of(
        &cam,
        s.pose.transform_point(&Vec3::new(
            s.shape.length * 0.5,
            0.0,
            s.shape.thickness * 0.5,
        )),
    );
    assert!(
        !differs(rgb(&coloured, px), rgb(&plain, px), 3),
        "a field must not recolour the blades"
    );
}

#[test]
fn overlays_and_skull_draw_and_bad_input_is_refused() {
    let Some(mut renderer) = renderer_or_skip("overlays_and_skull_draw") else {
        return;
    };
    let (positions, triangles) = ellipsoid(2);
    let spatulas = spatulas();
    let cam = OrbitCamera::microscope(Vec3::new(0.0, -0.04, 0.05), Vec3::new(0.0, 0.5, -1.0), 0.25);
    let nodes: Vec<Vec3> = (0..5)
        .map(|k| Vec3::new(-0.03 + 0.015 * k as f64, -0.06, 0.075))
        .collect();
    let pairs = [
        PairSegment {
            from: Vec3::new(-0.02, -0.07, 0.075),
            to: Vec3::new(-0.02, -0.07, 0.03),
            feasible: true,
        },
        PairSegment {
            from: Vec3::new(0.02, -0.07, 0.075),
            to: Vec3::new(0.02, -0.07, 0.03),
            feasible: false,
        },
    ];
    let skull = [SkullSphere {
        center: Vec3::zeros(),
        radius: 0.11,
        color: [0.9, 0.85, 0.7, 0.15],
    }];
    let mut view = SceneView::new(&positions, &triangles, cam);
    view.spatulas = &spatulas;
    view.overlays = Overlays {
        source_nodes: &nodes,
        node_size_m: 0.004,
        pairs: &pairs,
    };
    view.skull = &skull;
    renderer.render_offscreen(&view).expect("render");
    let img = read_offscreen(&renderer).expect("read back");
    save(&img, "render_microscope_overlays.png");

    let node_px = pixel_of(&cam, nodes[2]);
    assert!(
        any_near(&img, node_px, 1, |c| c[2] > 150 && c[0] < 120),
        "source node must be drawn blue on top near {node_px:?}"
    );
    let feasible_px = pixel_of(&cam, Vec3::new(-0.02, -0.07, 0.05));
    assert!(
        any_near(&img, feasible_px, 2, |c| c[1] > 180
            && c[0] < 140
            && c[1] > c[2] + 60),
        "feasible pair must be green near {feasible_px:?}"
    );
    let culled_px = pixel_of(&cam, Vec3::new(0.02, -0.07, 0.05));
    assert!(
        any_near(&img, culled_px, 2, |c| c[0] > 180
            && c[1] < 140
            && c[2] < 140),
        "culled pair must be red near {culled_px:?}"
    );

    // The translucent skull tints the background but lets the brain show through.
    view.skull = &[];
    renderer
        .render_offscreen(&view)
        .expect("render without skull");
    let bare = read_offscreen(&renderer).expect("read back");
    let tinted = img
        .pixels()
        .zip(bare.pixels())
        .filter(|(a, b)| (0..3).any(|k| (a.0[k] as i32 - b.0[k] as i32).abs() > 4))
        .count();
    assert!(
        tinted > (SIZE.0 * SIZE.1 / 4) as usize,
        "the skull sphere must tint what is behind it; only {tinted} pixels changed"
    );
    let brain = pixel_of(&cam, on_brain(Vec3::new(0.03, -0.02, 1.0)));
    assert!(
        is_pinkish(rgb(&img, brain)),
        "the brain must show through the translucent skull: {:?}",
        rgb(&img, brain)
    );

    // Bad input is an error, not a panic or a garbage frame.
    let short = vec![0.0; positions.len() - 1];
    view.surface.field = Some(ScalarField {
        values: &short,
        kind: FieldKind::Strain,
        map: ColorMap::Viridis,
        range: (0.0, 1.0),
    });
    assert!(
        matches!(
            renderer.render_offscreen(&view),
            Err(RenderError::FieldLength { .. })
        ),
        "short field must be refused"
    );
    view.surface.field = None;
    let mut broken = triangles.clone();
    broken[7][1] = positions.len() as u32;
    view.surface.triangles = &broken;
    assert!(
        matches!(
            renderer.render_offscreen(&view),
            Err(RenderError::TriangleIndex { triangle: 7, .. })
        ),
        "out-of-range index must be refused"
    );
    view.surface.triangles = &triangles;
    renderer
        .render_offscreen(&view)
        .expect("a good frame after refused ones");
}

#[test]
fn capture_writes_a_png() {
    let (positions, triangles) = ellipsoid(1);
    let view = SceneView::new(&positions, &triangles, camera());
    let path = std::env::temp_dir().join("render_capture_small.png");
    match fissure::render::capture::render_png(&view, (64, 48), &path) {
        Err(RenderError::NoAdapter(why)) => {
            println!("SKIP capture_writes_a_png: no GPU adapter ({why})")
        }
        Err(e) => panic!("render_png failed: {e}"),
        Ok(()) => {
            let img = image::open(&path).expect("PNG readable").to_rgba8();
            assert_eq!(
                img.dimensions(),
                (64, 48),
                "odd widths must survive the 256-byte row padding"
            );
            let centre = img.get_pixel(32, 24).0;
            assert!(
                centre[0] > 60,
                "the brain must be in the middle of the picture: {centre:?}"
            );
        }
    }
}

#[test]
fn phantom_brain_with_spatulas_in_the_fissure() {
    use fissure::mesh::phantom::{Landmarks, Preset, generate};
    let Some(mut renderer) = renderer_or_skip("phantom_brain_with_spatulas_in_the_fissure") else {
        return;
    };
    let phantom = generate(Preset::Small).expect("phantom Small");
    let boundary = phantom.mesh.boundary();
    let positions = boundary.gather_positions(&phantom.mesh.positions);
    let Landmarks::Brain(marks) = &phantom.landmarks else {
        panic!("Small is a brain preset")
    };
    let fissure = &marks.interhemispheric;
    // Blades along the fissure's inward direction, faces towards its walls, half inserted.
    let shape = SpatulaShape {
        length: 0.05,
        width: 0.01,
        thickness: 0.001,
    };
    let x = fissure.inward;
    let z = fissure.normal;
    let rotation = Quat::from_rotation_matrix(&nalgebra::Rotation3::from_basis_unchecked(&[
        x,
        z.cross(&x),
        z,
    ]));
    let place = |side: f64| Pose {
        position: fissure.entry - x * (shape.length * 0.5) + z * (side * 0.004),
        rotation,
    };
    let spatulas = [
        SpatulaView::new(shape, place(-1.0)),
        SpatulaView::new(shape, place(1.0)),
    ];
    let (lo, hi) = phantom.mesh.bounding_box();
    let cam = OrbitCamera::framing(lo, hi + Vec3::new(0.0, 0.0, 0.03));
    let mut view = SceneView::new(&positions, &boundary.triangles, cam);
    view.spatulas = &spatulas;
    renderer.render_offscreen(&view).expect("render phantom");
    let img = read_offscreen(&renderer).expect("read back");
    save(&img, "render_phantom_overview.png");
    let pink = img
        .pixels()
        .filter(|p| is_pinkish([p.0[0] as i32, p.0[1] as i32, p.0[2] as i32]))
        .count();
    assert!(
        pink > (SIZE.0 * SIZE.1 / 10) as usize,
        "phantom brain covers only {pink} pink pixels"
    );
    for (k, s) in spatulas.iter().enumerate() {
        // The handle end sticks out of the fissure above the brain.
        let handle = s
            .pose
            .transform_point(&Vec3::new(shape.length * 0.1, 0.0, 0.0));
        let px = pixel_of(&cam, handle);
        assert!(
            any_near(&img, px, 3, is_greyish),
            "spatula {k}: no grey blade pixel near {px:?}"
        );
    }
    view.camera = OrbitCamera::microscope(fissure.entry, fissure.inward, 0.15);
    renderer.render_offscreen(&view).expect("render microscope");
    save(
        &read_offscreen(&renderer).expect("read back"),
        "render_phantom_microscope.png",
    );
}

//! CPU-side geometry for one frame: surface normals and colours, blade boxes,
//! skull spheres, tether tubes, overlay squares and ribbons.
//!
//! In: a [`SceneView`]'s parts and the camera target (positions are emitted
//! relative to it, so f32 keeps ~0.1 µm resolution within a 1 m scene). Out:
//! [`Vertex`] arrays written into caller-owned `Vec`s (cleared, capacity
//! reused: no allocation once warm). Stays true: normals are unit or, for a
//! vertex only on degenerate triangles, +z; area weighting comes from the
//! unnormalised cross products.

use super::colormap::NO_DATA;
use super::gpu_types::Vertex;
use super::scene::{BRAIN_PINK, FieldKind, Overlays, SkullSphere, SpatulaView, SurfaceView, TetherSegment};
use crate::math::Vec3;

/// Per-vertex area-weighted normals of `triangles` over `positions`, written to
/// `normals` (resized to `positions.len()`). Triangles must index in range.
pub fn area_weighted_normals(positions: &[Vec3], triangles: &[[u32; 3]], normals: &mut Vec<Vec3>) {
    normals.clear();
    normals.resize(positions.len(), Vec3::zeros());
    for t in triangles {
        let [a, b, c] = t.map(|i| positions[i as usize]);
        // |cross| = 2 x area: summing unnormalised crosses weights by area.
        let n = (b - a).cross(&(c - a));
        if n.iter().all(|x| x.is_finite()) {
            for &i in t {
                normals[i as usize] += n;
            }
        }
    }
    for n in normals.iter_mut() {
        let len = n.norm();
        *n = if len > 0.0 && len.is_finite() {
            *n / len
        } else {
            Vec3::z()
        };
    }
}

fn rel(p: &Vec3, origin: &Vec3) -> [f32; 3] {
    let d = p - origin;
    [d.x as f32, d.y as f32, d.z as f32]
}

fn f3(v: &Vec3) -> [f32; 3] {
    [v.x as f32, v.y as f32, v.z as f32]
}

/// Fills the surface vertices: positions relative to `origin`, normals, colours
/// (from the field if any, else [`BRAIN_PINK`]). `normals` is scratch.
pub fn surface_vertices(
    surface: &SurfaceView,
    origin: &Vec3,
    normals: &mut Vec<Vec3>,
    out: &mut Vec<Vertex>,
) {
    area_weighted_normals(surface.positions, surface.triangles, normals);
    out.clear();
    out.reserve(surface.positions.len());
    for (i, (p, n)) in surface.positions.iter().zip(normals.iter()).enumerate() {
        let rgb = match &surface.field {
            Some(f) => f
                .values
                .get(i)
                .map_or(NO_DATA, |&v| f.map.color(v, f.range)),
            None => {
                let ao = surface.occlusion.get(i).copied().unwrap_or(1.0);
                BRAIN_PINK.map(|c| c * ao)
            }
        };
        // Alpha: the vertex's weight in the hidden-contact pass (the surface
        // pass draws opaque and ignores it): 1 where a blade presses.
        let pressed = pressed_value(surface, i);
        out.push(Vertex {
            position: rel(p, origin),
            normal: f3(n),
            color: [rgb[0], rgb[1], rgb[2], if pressed { 1.0 } else { 0.0 }],
        });
    }
}

/// Whether surface vertex `i` carries a contact pressure or a risk of infarct
/// above zero (only those fields have any): what lies under a blade shows
/// through it, the tissue a retractor presses being where both are.
fn pressed_value(surface: &SurfaceView, i: usize) -> bool {
    surface.field.as_ref().is_some_and(|f| {
        matches!(f.kind, FieldKind::ContactPressureMmHg | FieldKind::InfarctRisk) && f.values.get(i).is_some_and(|&v| v > 0.0 && v.is_finite())
    })
}

/// The triangles with a pressed vertex (alpha above 0 in `vertices`, from
/// [`surface_vertices`]), for the renderer's hidden-contact pass; empty
/// unless the field is pressure.
pub fn pressed_triangles(triangles: &[[u32; 3]], vertices: &[Vertex], out: &mut Vec<[u32; 3]>) {
    out.clear();
    out.extend(triangles.iter().filter(|t| t.iter().any(|&v| vertices.get(v as usize).is_some_and(|x| x.color[3] > 0.0))));
}

/// The six faces of a box in the spatula frame: (outward normal, four corners CCW from outside).
const BOX_FACES: [([f64; 3], [[f64; 3]; 4]); 6] = [
    (
        [0.0, 0.0, 1.0],
        [
            [0.0, -1.0, 1.0],
            [1.0, -1.0, 1.0],
            [1.0, 1.0, 1.0],
            [0.0, 1.0, 1.0],
        ],
    ),
    (
        [0.0, 0.0, -1.0],
        [
            [0.0, -1.0, -1.0],
            [0.0, 1.0, -1.0],
            [1.0, 1.0, -1.0],
            [1.0, -1.0, -1.0],
        ],
    ),
    (
        [0.0, 1.0, 0.0],
        [
            [0.0, 1.0, -1.0],
            [0.0, 1.0, 1.0],
            [1.0, 1.0, 1.0],
            [1.0, 1.0, -1.0],
        ],
    ),
    (
        [0.0, -1.0, 0.0],
        [
            [0.0, -1.0, -1.0],
            [1.0, -1.0, -1.0],
            [1.0, -1.0, 1.0],
            [0.0, -1.0, 1.0],
        ],
    ),
    (
        [1.0, 0.0, 0.0],
        [
            [1.0, -1.0, -1.0],
            [1.0, 1.0, -1.0],
            [1.0, 1.0, 1.0],
            [1.0, -1.0, 1.0],
        ],
    ),
    (
        [-1.0, 0.0, 0.0],
        [
            [0.0, -1.0, -1.0],
            [0.0, -1.0, 1.0],
            [0.0, 1.0, 1.0],
            [0.0, 1.0, -1.0],
        ],
    ),
];

/// Appends each blade as a solid box (36 vertices a blade): x in [0, length],
/// y in [-width/2, width/2], z in [-thickness/2, thickness/2], spatula frame.
pub fn blade_vertices(spatulas: &[SpatulaView], origin: &Vec3, out: &mut Vec<Vertex>) {
    for s in spatulas {
        let scale = Vec3::new(s.shape.length, s.shape.width * 0.5, s.shape.thickness * 0.5);
        let color = [s.color[0], s.color[1], s.color[2], 1.0];
        for (normal, corners) in BOX_FACES.iter() {
            let n = s.pose.transform_vector(&Vec3::from(*normal));
            let world =
                corners.map(|c| s.pose.transform_point(&Vec3::from(c).component_mul(&scale)));
            for k in [0, 1, 2, 0, 2, 3] {
                out.push(Vertex {
                    position: rel(&world[k], origin),
                    normal: f3(&n),
                    color,
                });
            }
        }
    }
}

/// Unit-sphere directions for skull spheres: `rings` x `segments` quads as triangles.
pub fn unit_sphere(rings: u32, segments: u32) -> Vec<Vec3> {
    let mut tris = Vec::with_capacity((rings * segments * 6) as usize);
    let dir = |r: u32, s: u32| {
        let theta = std::f64::consts::PI * r as f64 / rings as f64;
        let phi = std::f64::consts::TAU * s as f64 / segments as f64;
        Vec3::new(
            theta.sin() * phi.cos(),
            theta.sin() * phi.sin(),
            theta.cos(),
        )
    };
    for r in 0..rings {
        for s in 0..segments {
            let (a, b, c, d) = (dir(r, s), dir(r + 1, s), dir(r + 1, s + 1), dir(r, s + 1));
            // Counter-clockwise seen from outside.
            tris.extend_from_slice(&[a, b, c, a, c, d]);
        }
    }
    tris
}

/// Appends the skull spheres scaled from `unit` (from [`unit_sphere`]).
pub fn sphere_vertices(
    spheres: &[SkullSphere],
    unit: &[Vec3],
    origin: &Vec3,
    out: &mut Vec<Vertex>,
) {
    for s in spheres {
        for d in unit {
            let p = s.center + d * s.radius;
            out.push(Vertex {
                position: rel(&p, origin),
                normal: f3(d),
                color: s.color,
            });
        }
    }
}

/// Sides of an opaque tether tube (a vessel, a torn end's stub).
pub const TUBE_SIDES: u32 = 10;
/// Sides of a translucent strand (a band: a fine thread).
pub const STRAND_SIDES: u32 = 6;

/// Appends the tether tubes of `segments` whose opacity is 1 (`opaque`) or
/// below 1 (not `opaque`): a cylinder of `TUBE_SIDES` (opaque) or
/// `STRAND_SIDES` sides, CCW from outside; an opaque tube also gets a sphere
/// of its radius at each end from `unit_cap` ([`unit_sphere`]), so the
/// segments of a vessel join without gaps at its bends. A segment with no
/// length, no radius, or anything not finite is skipped.
pub fn tube_vertices(segments: &[TetherSegment], opaque: bool, unit_cap: &[Vec3], origin: &Vec3, out: &mut Vec<Vertex>) {
    for seg in segments {
        if (seg.alpha >= 1.0) != opaque {
            continue;
        }
        let r = f64::from(seg.radius_m);
        let axis = seg.b - seg.a;
        let length = axis.norm();
        if !(r > 0.0 && r.is_finite() && length > 1e-9 && length.is_finite()) || !seg.a.iter().all(|c| c.is_finite()) {
            continue;
        }
        let d = axis / length;
        // Any unit vector across the axis, and the third making (u, v, d) right-handed.
        let other = if d.x.abs() < 0.9 { Vec3::x() } else { Vec3::y() };
        let u = d.cross(&other).normalize();
        let v = d.cross(&u);
        let color = [seg.color[0], seg.color[1], seg.color[2], seg.alpha.clamp(0.0, 1.0)];
        let sides = if opaque { TUBE_SIDES } else { STRAND_SIDES };
        let around = |i: u32| {
            let t = std::f64::consts::TAU * f64::from(i) / f64::from(sides);
            u * t.cos() + v * t.sin()
        };
        for i in 0..sides {
            let (n0, n1) = (around(i), around(i + 1));
            let (a0, a1) = (seg.a + n0 * r, seg.a + n1 * r);
            let (b0, b1) = (seg.b + n0 * r, seg.b + n1 * r);
            for (p, n) in [(a0, n0), (a1, n1), (b1, n1), (a0, n0), (b1, n1), (b0, n0)] {
                out.push(Vertex { position: rel(&p, origin), normal: f3(&n), color });
            }
        }
        if opaque {
            for centre in [seg.a, seg.b] {
                for n in unit_cap {
                    out.push(Vertex { position: rel(&(centre + n * r), origin), normal: f3(n), color });
                }
            }
        }
    }
}

/// Overlay colours (linear RGB).
pub const NODE_COLOR: [f32; 4] = [0.1, 0.6, 1.0, 1.0];
pub const FEASIBLE_COLOR: [f32; 4] = [0.1, 0.9, 0.2, 1.0];
pub const CULLED_COLOR: [f32; 4] = [1.0, 0.1, 0.1, 1.0];

/// Appends source nodes as camera-facing squares and pairs as camera-facing
/// ribbons (a third of the node size wide, so they survive MSAA as clearly as
/// the nodes), all as triangles. `right`/`up` are the view's unit axes.
pub fn overlay_vertices(
    overlays: &Overlays,
    origin: &Vec3,
    right: &Vec3,
    up: &Vec3,
    default_size_m: f64,
    quads: &mut Vec<Vertex>,
) {
    let size = if overlays.node_size_m > 0.0 && overlays.node_size_m.is_finite() {
        overlays.node_size_m
    } else {
        default_size_m
    };
    let (r, u) = (right * (size * 0.5), up * (size * 0.5));
    let n = f3(&right.cross(up));
    for p in overlays.source_nodes {
        let c = [p - r - u, p + r - u, p + r + u, p - r + u];
        for k in [0, 1, 2, 0, 2, 3] {
            quads.push(Vertex {
                position: rel(&c[k], origin),
                normal: n,
                color: NODE_COLOR,
            });
        }
    }
    let towards_viewer = right.cross(up);
    for seg in overlays.pairs {
        let color = if seg.feasible {
            FEASIBLE_COLOR
        } else {
            CULLED_COLOR
        };
        let side = (seg.to - seg.from).cross(&towards_viewer);
        // A segment along the view direction shows as a dot: give it the right axis.
        let side = if side.norm() > 1e-12 {
            side.normalize()
        } else {
            *right
        } * (size / 6.0);
        let c = [
            seg.from - side,
            seg.to - side,
            seg.to + side,
            seg.from + side,
        ];
        for k in [0, 1, 2, 0, 2, 3] {
            quads.push(Vertex {
                position: rel(&c[k], origin),
                normal: n,
                color,
            });
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{Pose, SpatulaShape};

    #[test]
    fn only_pressed_triangles_show_through_and_only_for_pressure_and_risk() {
        use super::super::colormap::ColorMap;
        use super::super::scene::ScalarField;
        let p = vec![Vec3::zeros(), Vec3::x(), Vec3::y(), Vec3::new(1.0, 1.0, 0.0), Vec3::new(2.0, 1.0, 0.0)];
        let tris = [[0, 1, 2], [1, 3, 2], [1, 4, 3]];
        let values = [0.0, 0.0, 12.0, 0.0, f64::NAN];
        let field = |kind| ScalarField { values: &values, kind, map: ColorMap::Inferno, range: (0.0, 30.0) };
        let view = |f| SurfaceView { positions: &p, triangles: &tris, field: f, occlusion: &[] };
        let (mut out, mut normals, mut verts) = (Vec::new(), Vec::new(), Vec::new());
        surface_vertices(&view(Some(field(FieldKind::ContactPressureMmHg))), &Vec3::zeros(), &mut normals, &mut verts);
        assert_eq!(verts.iter().map(|v| v.color[3]).collect::<Vec<_>>(), vec![0.0, 0.0, 1.0, 0.0, 0.0], "NaN is not pressure");
        pressed_triangles(&tris, &verts, &mut out);
        assert_eq!(out, vec![[0, 1, 2], [1, 3, 2]], "the triangles around the pressed vertex");
        surface_vertices(&view(Some(field(FieldKind::InfarctRisk))), &Vec3::zeros(), &mut normals, &mut verts);
        pressed_triangles(&tris, &verts, &mut out);
        assert_eq!(out, vec![[0, 1, 2], [1, 3, 2]], "the tissue at risk shows through too");
        for other in [None, Some(field(FieldKind::DisplacementMm)), Some(field(FieldKind::Strain))] {
            surface_vertices(&view(other), &Vec3::zeros(), &mut normals, &mut verts);
            pressed_triangles(&tris, &verts, &mut out);
            assert!(out.is_empty(), "only a pressure or risk field shows through");
        }
    }

    #[test]
    fn normals_are_area_weighted() {
        // Vertex 0 is shared by a big triangle facing +z and a small one facing +x.
        let p = vec![
            Vec3::zeros(),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::new(0.0, 0.1, 0.0),
            Vec3::new(0.0, 0.0, 0.1),
        ];
        let tris = [[0, 1, 2], [0, 3, 4]];
        let mut n = Vec::new();
        area_weighted_normals(&p, &tris, &mut n);
        let expected = Vec3::new(0.01, 0.0, 1.0).normalize();
        assert!(
            (n[0] - expected).norm() < 1e-12,
            "weights must follow area: {:?}",
            n[0]
        );
        assert!((n[1] - Vec3::z()).norm() < 1e-12);
        assert!((n[3] - Vec3::x()).norm() < 1e-12);
    }

    #[test]
    fn degenerate_triangles_give_finite_normals() {
        let p = vec![
            Vec3::zeros(),
            Vec3::zeros(),
            Vec3::zeros(),
            Vec3::new(1.0, 1.0, 1.0),
        ];
        let mut n = Vec::new();
        area_weighted_normals(&p, &[[0, 1, 2]], &mut n);
        assert!(n.iter().all(|v| (v.norm() - 1.0).abs() < 1e-12), "{n:?}");
    }

    #[test]
    fn blade_box_faces_point_outward() {
        let s = SpatulaView::new(
            SpatulaShape {
                length: 0.06,
                width: 0.01,
                thickness: 0.001,
            },
            Pose::default(),
        );
        let mut out = Vec::new();
        blade_vertices(&[s], &Vec3::zeros(), &mut out);
        assert_eq!(out.len(), 36);
        let centre = Vec3::new(0.03, 0.0, 0.0);
        for tri in out.chunks(3) {
            let [a, b, c] = [0, 1, 2].map(|k| {
                Vec3::new(
                    tri[k].position[0] as f64,
                    tri[k].position[1] as f64,
                    tri[k].position[2] as f64,
                )
            });
            let winding = (b - a).cross(&(c - a));
            let n = Vec3::new(
                tri[0].normal[0] as f64,
                tri[0].normal[1] as f64,
                tri[0].normal[2] as f64,
            );
            assert!(
                winding.dot(&n) > 0.0,
                "triangle winding must agree with its normal"
            );
            assert!(
                ((a + b + c) / 3.0 - centre).dot(&n) > 0.0,
                "normal must point out of the box"
            );
        }
    }

    /// Tube triangles wind CCW seen from outside and their normals point away
    /// from the axis; opaque and translucent segments go to their own pass;
    /// a degenerate segment draws nothing.
    #[test]
    fn tubes_face_outward_and_split_by_opacity() {
        let seg = |alpha: f32, b: Vec3| TetherSegment { a: Vec3::zeros(), b, radius_m: 0.001, color: [1.0, 0.0, 0.0], alpha };
        let segments = [seg(1.0, Vec3::new(0.0, 0.0, 0.01)), seg(0.5, Vec3::new(0.01, 0.0, 0.0)), seg(1.0, Vec3::zeros())];
        let cap = unit_sphere(3, 6);
        let mut out = Vec::new();
        tube_vertices(&segments, true, &cap, &Vec3::zeros(), &mut out);
        assert_eq!(out.len(), (TUBE_SIDES * 6) as usize + 2 * cap.len(), "one opaque tube with its two caps");
        for tri in out[..(TUBE_SIDES * 6) as usize].chunks(3) {
            let p = tri.iter().map(|v| Vec3::new(v.position[0] as f64, v.position[1] as f64, v.position[2] as f64)).collect::<Vec<_>>();
            let winding = (p[1] - p[0]).cross(&(p[2] - p[0]));
            let centre = (p[0] + p[1] + p[2]) / 3.0;
            let radial = Vec3::new(centre.x, centre.y, 0.0);
            assert!(winding.dot(&radial) > 0.0, "tube triangle faces inward");
        }
        out.clear();
        tube_vertices(&segments, false, &cap, &Vec3::zeros(), &mut out);
        assert_eq!(out.len(), (STRAND_SIDES * 6) as usize, "one translucent strand, no caps");
        assert!(out.iter().all(|v| v.color[3] == 0.5));
    }

    #[test]
    fn sphere_is_ccw_from_outside() {
        let unit = unit_sphere(8, 12);
        for tri in unit.chunks(3) {
            let n = (tri[1] - tri[0]).cross(&(tri[2] - tri[0]));
            if n.norm() > 1e-12 {
                assert!(
                    n.dot(&(tri[0] + tri[1] + tri[2])) > 0.0,
                    "sphere triangle faces inward"
                );
            }
        }
    }
}

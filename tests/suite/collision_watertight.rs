//! Watertightness (seeded property test): a line from a point inside a closed
//! triangulated sphere crosses it exactly once in front and once behind, including
//! lines aimed exactly at vertices and at points of edges, and lines along the axes
//! through vertices whose coordinates are exact. Guards against the double hits and
//! lost hits of a plain Möller–Trumbore at shared edges.

use fissure::collision::scenes::icosphere;
use fissure::geometry::LineQuery;
use fissure::math::Vec3;

/// xorshift64*: a fixed-seed generator so failures replay exactly.
struct Rng(u64);
impl Rng {
    fn next_f64(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        (self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 / (1u64 << 53) as f64
    }
    fn in_ball(&mut self, r: f64) -> Vec3 {
        loop {
            let p = Vec3::new(self.next_f64() * 2.0 - 1.0, self.next_f64() * 2.0 - 1.0, self.next_f64() * 2.0 - 1.0);
            if p.norm() < 1.0 {
                return p * r;
            }
        }
    }
}

fn count(t: &[[u32; 3]], p: &[Vec3], origin: Vec3, dir: Vec3) -> (usize, usize) {
    let q = LineQuery::new(origin, dir).expect("valid line");
    let (mut front, mut behind) = (0, 0);
    for tri in t {
        if let Some(h) = q.intersect(&p[tri[0] as usize], &p[tri[1] as usize], &p[tri[2] as usize]) {
            assert!(h.t.is_finite() && h.u.is_finite() && h.v.is_finite(), "hit must be finite: {h:?}");
            if h.t > 0.0 { front += 1 } else { behind += 1 }
        }
    }
    (front, behind)
}

#[test]
fn lines_from_inside_a_closed_sphere_cross_it_once_each_way() {
    let centre = Vec3::new(0.01, -0.02, 0.03);
    let (t, p) = icosphere(centre, 0.05, 3);
    let mut rng = Rng(0x5eed_0001);
    let mut checked = 0;
    for case in 0..600 {
        let origin = centre + rng.in_ball(0.04);
        let target = match case % 3 {
            // Random direction.
            0 => origin + rng.in_ball(1.0),
            // Exactly at a vertex.
            1 => p[(rng.next_f64() * p.len() as f64) as usize % p.len()],
            // At a point of an edge (random fraction along it).
            _ => {
                let tri = t[(rng.next_f64() * t.len() as f64) as usize % t.len()];
                let s = rng.next_f64();
                p[tri[0] as usize] * (1.0 - s) + p[tri[1] as usize] * s
            }
        };
        let dir = target - origin;
        if dir.norm() < 1e-9 {
            continue;
        }
        let (front, behind) = count(&t, &p, origin, dir);
        assert_eq!((front, behind), (1, 1), "case {case}: line from {origin:?} toward {target:?} crossed ({front} front, {behind} behind)");
        checked += 1;
    }
    assert!(checked > 550, "too few cases ran");
    // The test has teeth: the textbook Möller–Trumbore (inclusive bounds) miscounts lines aimed at vertices.
    let mut rng = Rng(0x5eed_0002);
    let mut plain_wrong = 0;
    for _ in 0..100 {
        let origin = centre + rng.in_ball(0.04);
        let dir = p[(rng.next_f64() * p.len() as f64) as usize % p.len()] - origin;
        let hits = t.iter().filter(|tri| fissure::geometry::moller_trumbore(&origin, &dir, &p[tri[0] as usize], &p[tri[1] as usize], &p[tri[2] as usize]).is_some()).count();
        plain_wrong += (hits != 2) as usize;
    }
    assert!(plain_wrong > 0, "plain Möller–Trumbore should double-count some vertex hits; the cases do not reach vertices");
    // Axis-aligned lines through the centre hit the 6 icosahedron-free axis points; through exact vertices of a box, too.
    for dir in [Vec3::x(), Vec3::y(), Vec3::z(), Vec3::new(1.0, 1.0, 0.0), Vec3::new(1.0, 1.0, 1.0)] {
        assert_eq!(count(&t, &p, centre, dir), (1, 1), "axis line {dir:?} from the centre");
    }
    let (bt, bp) = fissure::collision::scenes::subdivided_box(Vec3::zeros(), Vec3::new(4.0, 4.0, 4.0), 4, 4);
    for origin in [Vec3::new(1.0, 1.0, 2.0), Vec3::new(2.0, 2.0, 2.0), Vec3::new(3.0, 1.0, 0.5)] {
        for dir in [Vec3::x(), Vec3::y(), Vec3::z(), Vec3::new(1.0, 1.0, 0.0)] {
            assert_eq!(count(&bt, &bp, origin, dir), (1, 1), "box: line from {origin:?} along {dir:?} through grid vertices and edges");
        }
    }
}

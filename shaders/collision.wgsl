// Collision compute pass: for every node-pair line (origin at the face-0 node,
// direction its normal, origin.w = blade thickness h), the nearest surface triangles
// behind and in front of BOTH nodes (face-0 node at t = 0, face-1 node at t = -h),
// brute force over all triangles (the paper's GPU method), f32. Same watertight line test and tie rules as `src/geometry/ray.rs`
// (Woop et al. 2013 with an (eps, eps^2) perturbation for edge functions that are
// exactly 0); triangles are visited in ascending order and only a strictly nearer
// hit replaces the kept one, so an exact tie goes to the lower triangle index.
// Positions and rays are relative to a centre chosen on the CPU (f32 precision).

struct Params {
    ray_count: u32,
    triangle_count: u32,
    _pad0: u32,
    _pad1: u32,
};

struct Ray {
    origin: vec4<f32>,
    direction: vec4<f32>,
};

struct Slot {
    triangle: u32,
    t: f32,
    u: f32,
    v: f32,
};

// a: largest t <= e (face 0 behind), b: smallest t > e (face 0 front),
// c: smallest t >= -h - e (face 1 behind), d: largest t < -h - e (face 1 front).
struct Hits {
    a: Slot,
    b: Slot,
    c: Slot,
    d: Slot,
};

const NO_HIT: u32 = 0xffffffffu;

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> positions: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> triangles: array<vec4<u32>>;
@group(0) @binding(3) var<storage, read> rays: array<Ray>;
@group(0) @binding(4) var<storage, read_write> hits: array<Hits>;

fn perturbed_sign(e: f32, dx: f32, dy: f32) -> i32 {
    if (e > 0.0) { return 1; }
    if (e < 0.0) { return -1; }
    if (dy > 0.0) { return 1; }
    if (dy < 0.0) { return -1; }
    if (dx < 0.0) { return 1; }
    if (dx > 0.0) { return -1; }
    return 0;
}

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let r = gid.x;
    if (r >= params.ray_count) {
        return;
    }
    let o = rays[r].origin.xyz;
    let h = rays[r].origin.w;
    let e = rays[r].direction.w; // contact tolerance (see backend/mod.rs)
    let d = rays[r].direction.xyz;
    let none = Slot(NO_HIT, 0.0, 0.0, 0.0);
    var out = Hits(none, none, none, none);
    let ad = abs(d);
    var kz: u32 = 2u;
    if (ad.x >= ad.y && ad.x >= ad.z) {
        kz = 0u;
    } else if (ad.y >= ad.z) {
        kz = 1u;
    }
    if (d[kz] == 0.0) {
        hits[r] = out;
        return;
    }
    let kx = (kz + 1u) % 3u;
    let ky = (kx + 1u) % 3u;
    let sz = 1.0 / d[kz];
    let sx = d[kx] * sz;
    let sy = d[ky] * sz;
    for (var k: u32 = 0u; k < params.triangle_count; k = k + 1u) {
        let tri = triangles[k];
        let a = positions[tri.x].xyz - o;
        let b = positions[tri.y].xyz - o;
        let c = positions[tri.z].xyz - o;
        let ax = a[kx] - sx * a[kz];
        let ay = a[ky] - sy * a[kz];
        let bx = b[kx] - sx * b[kz];
        let by = b[ky] - sy * b[kz];
        let cx = c[kx] - sx * c[kz];
        let cy = c[ky] - sy * c[kz];
        let eu = cx * by - cy * bx;
        let ev = ax * cy - ay * cx;
        let ew = bx * ay - by * ax;
        let su = perturbed_sign(eu, cx - bx, cy - by);
        let sv = perturbed_sign(ev, ax - cx, ay - cy);
        let sw = perturbed_sign(ew, bx - ax, by - ay);
        if (su == 0 || su != sv || su != sw) {
            continue;
        }
        let det = eu + ev + ew;
        if (det == 0.0) {
            continue;
        }
        let inv = 1.0 / det;
        let t = (eu * (sz * a[kz]) + ev * (sz * b[kz]) + ew * (sz * c[kz])) * inv;
        let u = ev * inv;
        let v = ew * inv;
        // Reject non-finite values (a vanishing determinant): x - x is 0 only when x is finite.
        if (!((t - t) == 0.0) || !((u - u) == 0.0) || !((v - v) == 0.0)) {
            continue;
        }
        let hit = Slot(k, t, u, v);
        if (t <= e) {
            if (out.a.triangle == NO_HIT || t > out.a.t) { out.a = hit; }
        } else {
            if (out.b.triangle == NO_HIT || t < out.b.t) { out.b = hit; }
        }
        if (t >= -h - e) {
            if (out.c.triangle == NO_HIT || t < out.c.t) { out.c = hit; }
        } else {
            if (out.d.triangle == NO_HIT || t > out.d.t) { out.d = hit; }
        }
    }
    hits[r] = out;
}

// Collision traversal: one thread per node-pair line (origin at the face-0 node,
// direction its normal; origin.w = blade thickness h, direction.w = contact
// tolerance e). It walks the refit BVH near-first and returns, for each of the four
// nearest-hit slots of the line, up to three CANDIDATE triangles (original indices).
// The CPU then decides every slot in f64 from the candidates (`backend/gpu.rs`), so
// the answers are the f64 backends' answers bit for bit; this pass only has to make
// sure the f64 winner is among the candidates, or flag the line for the CPU.
//
// Slots (line parameter t; thresholds T0 = e, T1 = -h - e; window w):
//   0 a: face 0 behind, largest t  <= T0 (accepts t32 <= T0 + w)
//   1 b: face 0 front,  smallest t >  T0 (accepts t32 >  T0 - w)
//   2 c: face 1 behind, smallest t >= T1 (accepts t32 >= T1 - w)
//   3 d: face 1 front,  largest t  <  T1 (accepts t32 <  T1 + w)
// Each slot keeps its best four by key (key = t for b and c, -t for a and d; an
// exact tie goes to the lower triangle index). An entry is SURE when each of its
// three f32 edge functions has the same sign beyond its error bound ee (the f64 test
// then hits that triangle too), and CLEAR when it is sure and its t32 lies more than
// w from the slot's threshold (its f64 side is then certain as well). A near miss
// or an f32 hit within ee of an edge is a candidate but never clear: a line passing
// within rounding OUTSIDE a silhouette edge is an f32 near miss of both triangles
// there and an f64 miss of both, so it proves no hit and must not bound the slot
// (it would prune the true hit farther along the line). The f64 winner has
// key <= (first clear entry's key) + w, so the slot returns its best three and
// flags the line when its fourth is also that close (a cluster of four: e.g. two
// triangles on the blade plane and two more within w), or when no clear entry
// exists among four. Hits whose f32 error bound exceeds w/8
// (a line grazing a triangle) are remembered with their t range; the line is
// flagged when such a range meets the final needed interval.
// The same watertight line test and edge rules as `src/geometry/ray.rs` (Woop et
// al. 2013), f32, coordinates relative to a centre chosen on the CPU. No value here
// is ever infinite or NaN: the shader language lets compilers assume so.

struct Params {
    line_count: u32,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
    window: f32,      // w, metres
    coord_scale: f32, // S: largest |coordinate| of positions and origins (relative to the centre)
    _pad3: f32,
    _pad4: f32,
};

struct Ray {
    origin: vec4<f32>,
    direction: vec4<f32>,
};

const NO_HIT: u32 = 0xffffffffu;
const BIG: f32 = 1.0e30;
const EPS: f32 = 1.1920929e-7;
const STACK: u32 = 64u;
const UNCERTAIN_MAX: u32 = 4u;
// Per line out: 12 candidate ids (a1 a2 a3 b1 .. d3) and a flag word (0: the
// candidates decide the line; bit 1: a cluster of four, 2: a grazing hit or too
// many of them, 4: the stack was full).
const OUT_STRIDE: u32 = 13u;

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> positions: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> topo: array<vec4<u32>>;
@group(0) @binding(3) var<storage, read> boxes: array<vec4<f32>>;
// Per leaf-order triangle: (v0, v1, v2, original index).
@group(0) @binding(4) var<storage, read> leaf_tris: array<vec4<u32>>;
@group(0) @binding(5) var<storage, read> rays: array<Ray>;
@group(0) @binding(6) var<storage, read_write> out: array<u32>;

fn perturbed_sign(e: f32, dx: f32, dy: f32) -> i32 {
    if (e > 0.0) { return 1; }
    if (e < 0.0) { return -1; }
    if (dy > 0.0) { return 1; }
    if (dy < 0.0) { return -1; }
    if (dx < 0.0) { return 1; }
    if (dx > 0.0) { return -1; }
    return 0;
}

var<private> keys: array<f32, 16>;
// 1u: the entry is a sure hit (see the header); only sure entries can be clear.
var<private> sure: array<u32, 16>;
var<private> ids: array<u32, 12>;
var<private> counts: array<u32, 4>;
var<private> thresholds: vec2<f32>;
var<private> win: f32;

fn key_of(s: u32, t: f32) -> f32 {
    if (s == 0u || s == 3u) { return -t; }
    return t;
}

fn threshold_of(s: u32) -> f32 {
    if (s < 2u) { return thresholds.x; }
    return thresholds.y;
}

fn accepts(s: u32, t: f32) -> bool {
    switch s {
        case 0u: { return t <= thresholds.x + win; }
        case 1u: { return t > thresholds.x - win; }
        case 2u: { return t >= thresholds.y - win; }
        default: { return t < thresholds.y + win; }
    }
}

// Entries with key <= the returned bound may still be the slot's f64 winner.
fn slot_bound(s: u32) -> f32 {
    let thr = threshold_of(s);
    for (var q = 0u; q < counts[s]; q = q + 1u) {
        let k = keys[4u * s + q];
        if (sure[4u * s + q] == 1u && abs(key_of(s, k) - thr) > win) {
            return k + win;
        }
    }
    return BIG;
}

fn insert(s: u32, k: f32, tri: u32, certain: u32) {
    let base = 4u * s;
    let cnt = counts[s];
    var pos = cnt;
    for (var q = 0u; q < cnt; q = q + 1u) {
        let kq = keys[base + q];
        if (k < kq || (k == kq && q < 3u && tri < ids[3u * s + q])) {
            pos = q;
            break;
        }
    }
    if (pos >= 4u) {
        return;
    }
    var q = 3u;
    loop {
        if (q <= pos) { break; }
        keys[base + q] = keys[base + q - 1u];
        sure[base + q] = sure[base + q - 1u];
        if (q < 3u) {
            ids[3u * s + q] = ids[3u * s + q - 1u];
        }
        q = q - 1u;
    }
    keys[base + pos] = k;
    sure[base + pos] = certain;
    if (pos < 3u) {
        ids[3u * s + pos] = tri;
    }
    counts[s] = min(cnt + 1u, 4u);
}

// The needed interval of t: hits outside it cannot change any slot.
fn needed() -> vec2<f32> {
    let lo = min(-slot_bound(0u), -slot_bound(3u));
    let hi = max(slot_bound(1u), slot_bound(2u));
    return vec2<f32>(lo, hi);
}

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let r = gid.x;
    if (r >= params.line_count) {
        return;
    }
    let o = rays[r].origin.xyz;
    let h = rays[r].origin.w;
    let e = rays[r].direction.w;
    let d = rays[r].direction.xyz;
    thresholds = vec2<f32>(e, -h - e);
    win = params.window;
    for (var i = 0u; i < 4u; i = i + 1u) {
        counts[i] = 0u;
    }
    for (var i = 0u; i < 12u; i = i + 1u) {
        ids[i] = NO_HIT;
    }
    var flag = 0u;
    let ob = r * OUT_STRIDE;

    let ad = abs(d);
    var kz: u32 = 2u;
    if (ad.x >= ad.y && ad.x >= ad.z) {
        kz = 0u;
    } else if (ad.y >= ad.z) {
        kz = 1u;
    }
    if (d[kz] == 0.0) {
        for (var i = 0u; i < 12u; i = i + 1u) { out[ob + i] = NO_HIT; }
        out[ob + 12u] = 0u;
        return;
    }
    let kx = (kz + 1u) % 3u;
    let ky = (kx + 1u) % 3u;
    let sz = 1.0 / d[kz];
    let sx = d[kx] * sz;
    let sy = d[ky] * sz;
    // Reciprocal direction for the slab test, never infinite.
    let dd = select(d, select(vec3<f32>(1.0e-30), vec3<f32>(-1.0e-30), d < vec3<f32>(0.0)), abs(d) < vec3<f32>(1.0e-30));
    let inv = 1.0 / dd;
    // Error of one sheared coordinate against the f64 line: f32 rounding of positions,
    // origin, direction and the shear (doubled for safety); see gpu.rs.
    let scale = params.coord_scale;
    // Blade centre (line parameter -h/2), for near-first ordering.
    let centre = -0.5 * h;

    var un_lo: array<f32, 4>;
    var un_hi: array<f32, 4>;
    var un_count = 0u;

    var stack_node: array<u32, 64>;
    var stack_t: array<vec2<f32>, 64>;
    var sp = 0u;
    {
        let ta = (boxes[0].xyz - o) * inv;
        let tb = (boxes[1].xyz - o) * inv;
        let t0 = max(max(min(ta.x, tb.x), min(ta.y, tb.y)), min(ta.z, tb.z));
        let t1 = min(min(max(ta.x, tb.x), max(ta.y, tb.y)), max(ta.z, tb.z));
        if (t0 <= t1) {
            stack_node[0] = 0u;
            stack_t[0] = vec2<f32>(t0, t1);
            sp = 1u;
        }
    }
    var need = vec2<f32>(-BIG, BIG);
    loop {
        if (sp == 0u) { break; }
        sp = sp - 1u;
        let node = stack_node[sp];
        let iv = stack_t[sp];
        if (iv.y < need.x || iv.x > need.y) {
            continue;
        }
        let n = topo[node];
        if (n.y > 0u) {
            for (var i = 0u; i < n.y; i = i + 1u) {
                let tri = leaf_tris[n.x + i];
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
                let za = sz * a[kz];
                let zb = sz * b[kz];
                let zc = sz * c[kz];
                // Coordinate error against the f64 line, then the edge functions' error.
                let reach = max(max(max(abs(ax), abs(ay)), max(abs(bx), abs(by))), max(max(abs(cx), abs(cy)), max(abs(za), max(abs(zb), abs(zc)))));
                let dc = 2.0 * EPS * (scale + 2.0 * reach);
                let ee = 2.0 * dc * (abs(ax) + abs(ay) + abs(bx) + abs(by) + abs(cx) + abs(cy)) + 2.0 * EPS * (abs(cx * by) + abs(cy * bx) + abs(ax * cy) + abs(ay * cx) + abs(bx * ay) + abs(by * ax));
                let inside = !(su == 0 || su != sv || su != sw);
                // Every edge function beyond its error: the f64 edge functions have the
                // same strict sign, so the f64 test hits this triangle (a sure hit).
                let certain = select(0u, 1u, (eu > ee && ev > ee && ew > ee) || (eu < -ee && ev < -ee && ew < -ee));
                // A near miss (within rounding of the inside) may be an f64 hit with no f32
                // neighbour to stand for it (a line touching a silhouette vertex or edge):
                // it becomes a candidate like a hit, and the CPU decides.
                let near = (eu >= -ee && ev >= -ee && ew >= -ee) || (eu <= ee && ev <= ee && ew <= ee);
                if (!inside && !near) {
                    continue;
                }
                let det = eu + ev + ew;
                let zlo = min(min(za, zb), zc);
                let zhi = max(max(za, zb), zc);
                if (abs(det) <= 2.0 * ee) {
                    // Grazing: t is anywhere on the triangle's extent along the line.
                    if (un_count < UNCERTAIN_MAX) {
                        un_lo[un_count] = zlo - dc;
                        un_hi[un_count] = zhi + dc;
                        un_count = un_count + 1u;
                    } else {
                        flag = flag | 2u;
                    }
                    continue;
                }
                let t = (eu * za + ev * zb + ew * zc) / det;
                let err_t = dc + 2.0 * ee * (zhi - zlo) / abs(det) + 4.0 * EPS * abs(t);
                if (err_t > 0.125 * win) {
                    if (un_count < UNCERTAIN_MAX) {
                        un_lo[un_count] = max(zlo, t - err_t) - dc;
                        un_hi[un_count] = min(zhi, t + err_t) + dc;
                        un_count = un_count + 1u;
                    } else {
                        flag = flag | 2u;
                    }
                }
                for (var s = 0u; s < 4u; s = s + 1u) {
                    if (accepts(s, t)) {
                        insert(s, key_of(s, t), tri.w, certain);
                    }
                }
            }
            need = needed();
            continue;
        }
        let l = n.x;
        let la = (boxes[2u * l].xyz - o) * inv;
        let lb = (boxes[2u * l + 1u].xyz - o) * inv;
        let a0 = max(max(min(la.x, lb.x), min(la.y, lb.y)), min(la.z, lb.z));
        let a1 = min(min(max(la.x, lb.x), max(la.y, lb.y)), max(la.z, lb.z));
        let ra = (boxes[2u * l + 2u].xyz - o) * inv;
        let rb = (boxes[2u * l + 3u].xyz - o) * inv;
        let b0 = max(max(min(ra.x, rb.x), min(ra.y, rb.y)), min(ra.z, rb.z));
        let b1 = min(min(max(ra.x, rb.x), max(ra.y, rb.y)), max(ra.z, rb.z));
        let keep_l = a0 <= a1 && a1 >= need.x && a0 <= need.y;
        let keep_r = b0 <= b1 && b1 >= need.x && b0 <= need.y;
        if (sp + 2u > STACK) {
            flag = flag | 4u;
            break;
        }
        let gl = max(max(a0 - centre, centre - a1), 0.0);
        let gr = max(max(b0 - centre, centre - b1), 0.0);
        if (keep_l && keep_r) {
            if (gl <= gr) {
                stack_node[sp] = l + 1u; stack_t[sp] = vec2<f32>(b0, b1);
                stack_node[sp + 1u] = l; stack_t[sp + 1u] = vec2<f32>(a0, a1);
            } else {
                stack_node[sp] = l; stack_t[sp] = vec2<f32>(a0, a1);
                stack_node[sp + 1u] = l + 1u; stack_t[sp + 1u] = vec2<f32>(b0, b1);
            }
            sp = sp + 2u;
        } else if (keep_l) {
            stack_node[sp] = l; stack_t[sp] = vec2<f32>(a0, a1);
            sp = sp + 1u;
        } else if (keep_r) {
            stack_node[sp] = l + 1u; stack_t[sp] = vec2<f32>(b0, b1);
            sp = sp + 1u;
        }
    }
    // Clusters of four, or no clear entry among four: the CPU decides the line.
    for (var s = 0u; s < 4u; s = s + 1u) {
        if (counts[s] == 4u && keys[4u * s + 3u] <= slot_bound(s)) {
            flag = flag | 1u;
        }
    }
    // A grazing hit whose t range meets the needed interval: the CPU decides the line.
    let fin = needed();
    for (var i = 0u; i < un_count; i = i + 1u) {
        if (un_hi[i] >= fin.x - win && un_lo[i] <= fin.y + win) {
            flag = flag | 2u;
        }
    }
    for (var i = 0u; i < 12u; i = i + 1u) {
        out[ob + i] = ids[i];
    }
    out[ob + 12u] = flag;
}

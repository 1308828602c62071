// BVH refit, one dispatch per tree level (height above the leaves), leaves first:
// a node's box is the union of its children's boxes (already refit by an earlier
// dispatch of the same pass) or, for a leaf, of its distinct vertices, grown by
// `level.margin`. Coordinates are f32 relative to a centre chosen on the CPU.
// Min and max are exact in f32, so a box holds its triangles' f32 vertices exactly
// before the margin is added.

struct Level {
    start: u32,   // first entry of this level in level_nodes
    count: u32,   // nodes in this level
    margin: f32,  // metres added on every side of a leaf box
    _pad: u32,
};

@group(0) @binding(0) var<uniform> level: Level;
@group(0) @binding(1) var<storage, read> positions: array<vec4<f32>>;
// Per node: (first, count, vfirst, vcount); count == 0: children at first and first + 1.
@group(0) @binding(2) var<storage, read> topo: array<vec4<u32>>;
@group(0) @binding(3) var<storage, read> leaf_vertices: array<u32>;
@group(0) @binding(4) var<storage, read> level_nodes: array<u32>;
// Per node two entries: lo (xyz), hi (xyz).
@group(0) @binding(5) var<storage, read_write> boxes: array<vec4<f32>>;

@compute @workgroup_size(64)
fn refit(@builtin(global_invocation_id) gid: vec3<u32>) {
    if (gid.x >= level.count) {
        return;
    }
    let k = level_nodes[level.start + gid.x];
    let n = topo[k];
    var lo = vec3<f32>(3.0e38);
    var hi = vec3<f32>(-3.0e38);
    if (n.y > 0u) {
        for (var i = 0u; i < n.w; i = i + 1u) {
            let p = positions[leaf_vertices[n.z + i]].xyz;
            lo = min(lo, p);
            hi = max(hi, p);
        }
        lo = lo - vec3<f32>(level.margin);
        hi = hi + vec3<f32>(level.margin);
    } else {
        let c = n.x;
        lo = min(boxes[2u * c].xyz, boxes[2u * (c + 1u)].xyz);
        hi = max(boxes[2u * c + 1u].xyz, boxes[2u * (c + 1u) + 1u].xyz);
    }
    boxes[2u * k] = vec4<f32>(lo, 0.0);
    boxes[2u * k + 1u] = vec4<f32>(hi, 0.0);
}

// Brain surface: per-vertex colour (plain pink, darkened in the sulci, or a
// scalar field), two-sided lighting (the opened fissure shows inner walls), a
// key light plus a headlight, soft wrap diffuse, a faint specular and, on the
// plain brain, the wet glint of the microscope's coaxial light.
// Positions arrive relative to the camera target (metres, f32).

struct Globals {
    view_proj: mat4x4<f32>,
    eye: vec4<f32>,
    light_dir: vec4<f32>,
    params: vec4<f32>, // x ambient, y specular strength, z shininess, w wet (the microscope's coaxial highlight)
};

@group(0) @binding(0) var<uniform> globals: Globals;

struct VsIn {
    @location(0) position: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) color: vec4<f32>,
};

struct VsOut {
    // Invariant: the hidden-contact pass must find the surface pass's depth.
    @builtin(position) @invariant clip: vec4<f32>,
    @location(0) world: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) color: vec4<f32>,
};

@vertex
fn vs_main(v: VsIn) -> VsOut {
    var out: VsOut;
    out.clip = globals.view_proj * vec4<f32>(v.position, 1.0);
    out.world = v.position;
    out.normal = v.normal;
    out.color = v.color;
    return out;
}

// The contact patch where something nearer hides it (drawn with depth test
// "greater", no depth write, alpha blended): lit as the surface is, faded by
// the vertex alpha (1 where a blade presses, 0 elsewhere) to 0.7 at most.
@fragment
fn fs_hidden(in: VsOut, @builtin(front_facing) front: bool) -> @location(0) vec4<f32> {
    return vec4<f32>(shade(in, front), 0.7 * clamp(in.color.a, 0.0, 1.0));
}

@fragment
fn fs_main(in: VsOut, @builtin(front_facing) front: bool) -> @location(0) vec4<f32> {
    return vec4<f32>(shade(in, front), 1.0);
}

fn shade(in: VsOut, front: bool) -> vec3<f32> {
    var n = normalize(in.normal);
    if (!front) {
        n = -n;
    }
    let v = normalize(globals.eye.xyz - in.world);
    let l = normalize(globals.light_dir.xyz);
    let wrap = 0.35;
    let key = max((dot(n, l) + wrap) / (1.0 + wrap), 0.0);
    let head = max(dot(n, v), 0.0);
    let h = normalize(l + v);
    let spec = pow(max(dot(n, h), 0.0), globals.params.z) * globals.params.y;
    // The microscope lights along its own axis: a wet surface glints where it faces the eye.
    let wet = pow(head, 90.0) * 0.35 * globals.params.w;
    let albedo = in.color.rgb;
    return albedo * (globals.params.x + 0.5 * key + 0.35 * head) + vec3<f32>(spec + wet);
}

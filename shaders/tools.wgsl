// Tools and overlays: metallic blades (fs_lit, opaque), translucent skull
// spheres (fs_lit with the vertex alpha, blended), overlay squares and pair
// ribbons (fs_unlit). Same vertex format and globals as surface.wgsl.

struct Globals {
    view_proj: mat4x4<f32>,
    eye: vec4<f32>,
    light_dir: vec4<f32>,
    params: vec4<f32>,
};

@group(0) @binding(0) var<uniform> globals: Globals;

struct VsIn {
    @location(0) position: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) color: vec4<f32>,
};

struct VsOut {
    @builtin(position) clip: vec4<f32>,
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

// Brushed steel: low diffuse, strong tight highlight, a Fresnel-like rim and a
// headlight so a blade seen edge-on or from behind the light still reads.
@fragment
fn fs_lit(in: VsOut) -> @location(0) vec4<f32> {
    let n = normalize(in.normal);
    let v = normalize(globals.eye.xyz - in.world);
    let l = normalize(globals.light_dir.xyz);
    let ndl = max(dot(n, l), 0.0);
    let ndv = max(dot(n, v), 0.0);
    let h = normalize(l + v);
    let spec = pow(max(dot(n, h), 0.0), 48.0) * 0.5;
    let rim = pow(1.0 - ndv, 4.0) * 0.25;
    let albedo = in.color.rgb;
    let rgb = albedo * (0.22 + 0.45 * ndl + 0.25 * ndv) + vec3<f32>(spec + rim);
    return vec4<f32>(rgb, in.color.a);
}

@fragment
fn fs_unlit(in: VsOut) -> @location(0) vec4<f32> {
    return in.color;
}

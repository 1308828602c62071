//! `#[repr(C)]` Pod twins of the structs the shaders read.
//!
//! In/out: plain bytes for wgpu buffers. Stays true: the sizes and field
//! offsets match `shaders/surface.wgsl` and `shaders/tools.wgsl` (size tests
//! below; WGSL uniform structs round up to 16 bytes).

use bytemuck::{Pod, Zeroable};

/// One vertex of every mesh we draw (surface, blades, spheres, overlays).
/// Positions are relative to the camera target, metres, f32.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct Vertex {
    pub position: [f32; 3],
    pub normal: [f32; 3],
    /// Linear RGBA.
    pub color: [f32; 4],
}

impl Vertex {
    /// Vertex buffer layout: location 0 position, 1 normal, 2 colour.
    pub const ATTRIBUTES: [wgpu::VertexAttribute; 3] =
        wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x3, 2 => Float32x4];

    pub fn layout() -> wgpu::VertexBufferLayout<'static> {
        wgpu::VertexBufferLayout {
            array_stride: std::mem::size_of::<Vertex>() as wgpu::BufferAddress,
            step_mode: wgpu::VertexStepMode::Vertex,
            attributes: &Self::ATTRIBUTES,
        }
    }
}

/// Per-frame uniforms (`Globals` in both shaders).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct Globals {
    /// Column-major view-projection (world relative to the camera target -> clip).
    pub view_proj: [[f32; 4]; 4],
    /// Eye position relative to the camera target (w unused).
    pub eye: [f32; 4],
    /// Unit direction towards the key light (w unused).
    pub light_dir: [f32; 4],
    /// x: ambient 0..1, y: specular strength 0..1, z: shininess, w unused.
    pub params: [f32; 4],
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_match_the_shaders() {
        // WGSL: vec3 + vec3 + vec4 in a vertex buffer is tightly packed.
        assert_eq!(std::mem::size_of::<Vertex>(), 40);
        assert_eq!(std::mem::offset_of!(Vertex, normal), 12);
        assert_eq!(std::mem::offset_of!(Vertex, color), 24);
        // WGSL: mat4x4 (64) + 3 x vec4 (48), a multiple of 16.
        assert_eq!(std::mem::size_of::<Globals>(), 112);
        assert_eq!(std::mem::size_of::<Globals>() % 16, 0);
    }
}

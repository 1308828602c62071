//! Rendering: the deformed brain surface, the spatulas, overlays, skull
//! spheres and tether tubes, with wgpu; offscreen capture for screenshots and `replay --frames`.
//!
//! In: a [`SceneView`] per frame (plain data: positions, triangles, an optional
//! scalar field, spatula shapes and poses, a camera). Out: pixels in a window
//! surface ([`window::WindowRenderer`]) or an image/PNG ([`capture`]). Stays
//! true: the simulation never imports this module; this module reads only
//! plain data; GPU absence or errors surface as [`RenderError`], never panics.

pub mod camera;
pub mod capture;
pub mod colormap;
pub mod gpu_types;
pub mod legend;
pub mod meshes;
pub mod occlusion;
pub mod renderer;
pub mod scene;
pub mod tethers;
pub mod window;

pub use camera::OrbitCamera;
pub use colormap::ColorMap;
pub use renderer::Renderer;
pub use scene::{
    FieldKind, Overlays, PairSegment, ScalarField, SceneView, SkullSphere, SpatulaView, SurfaceView,
    TetherSegment,
};

use std::path::PathBuf;

/// Rendering errors.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    #[error(
        "no GPU adapter found ({0}); headless: set VK_DRIVER_FILES=/usr/share/vulkan/icd.d/lvp_icd.x86_64.json WGPU_BACKEND=vulkan"
    )]
    NoAdapter(String),
    #[error("cannot open the GPU device: {0}")]
    Device(String),
    #[error("cannot create a window surface: {0}")]
    Surface(String),
    #[error("image size {width}x{height} is outside 1..=8192")]
    Size { width: u32, height: u32 },
    #[error("the scalar field has {values} values but the surface has {vertices} vertices")]
    FieldLength { values: usize, vertices: usize },
    #[error(
        "triangle {triangle} refers to vertex {index}, but the surface has {vertices} vertices"
    )]
    TriangleIndex {
        triangle: usize,
        index: u32,
        vertices: usize,
    },
    #[error("the camera has a non-finite target or a non-positive distance")]
    Camera,
    #[error("this renderer has no offscreen target")]
    NoOffscreenTarget,
    #[error("GPU error: {0}")]
    Gpu(String),
    #[error("reading the image back failed: {0}")]
    Readback(String),
    #[error("cannot write {path}: {message}")]
    Png { path: PathBuf, message: String },
}

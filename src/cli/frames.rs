//! PNG frames of a replay (`replay --frames`): the offscreen renderer draws each
//! frame's deformed surface and spatulas to `DIR/frames/frame_NNNNN.png`.

use std::path::{Path, PathBuf};

use anyhow::Context;
use fissure::render::camera::OrbitCamera;
use fissure::render::scene::{SceneView, SpatulaView};
use fissure::render::{Renderer, capture};
use fissure::sim::{Pipeline, SimState};

/// Image size of replay frames.
pub const FRAME_SIZE: (u32, u32) = (960, 720);

/// Writes one PNG a frame with a kept renderer.
pub struct FrameWriter {
    dir: PathBuf,
    renderer: Option<Renderer>,
    camera: Option<OrbitCamera>,
    spatulas: Vec<SpatulaView>,
}

impl FrameWriter {
    pub fn new(out_dir: &Path) -> anyhow::Result<Self> {
        let dir = out_dir.join("frames");
        std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
        Ok(Self { dir, renderer: None, camera: None, spatulas: Vec::new() })
    }

    pub fn write(&mut self, pipeline: &Pipeline, state: &SimState) -> anyhow::Result<()> {
        if self.renderer.is_none() {
            self.renderer = Some(Renderer::new_offscreen(FRAME_SIZE).context("starting the offscreen renderer")?);
            let (lo, hi) = pipeline.mesh().bounding_box();
            self.camera = Some(OrbitCamera::framing(lo, hi));
        }
        let (Some(renderer), Some(camera)) = (self.renderer.as_mut(), self.camera) else { unreachable!() };
        self.spatulas.clear();
        for (shape, pose) in pipeline.spatula_shapes().iter().zip(&state.poses) {
            self.spatulas.push(SpatulaView::new(*shape, *pose));
        }
        let mut view = SceneView::new(&state.surface_positions, &pipeline.surface().triangles, camera);
        view.spatulas = &self.spatulas;
        renderer.render_offscreen(&view).context("rendering a frame")?;
        let image = capture::read_offscreen(renderer).context("reading the frame back")?;
        let path = self.dir.join(format!("frame_{:05}.png", state.frame.saturating_sub(1)));
        capture::save_png(&image, &path).with_context(|| format!("writing {}", path.display()))?;
        Ok(())
    }
}

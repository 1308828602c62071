//! Offscreen frames: the drawing `fissure screenshot` and `replay --frames`
//! share (the window draws through the same [`fissure::app::draw`] code).
//!
//! In: the pipeline and its state after a step, drawing switches, a view
//! preset. Out: an RGBA image or PNG (`replay --frames` writes
//! `DIR/frames/frame_NNNNN.png`). Stays true: one renderer is kept for all
//! frames; what is drawn comes from `Snapshot::capture` + `SceneBuffers::view`.

use std::path::{Path, PathBuf};

use anyhow::Context;
use fissure::app::draw::{DrawOptions, SceneBuffers, SceneStatic, Snapshot, ViewPreset, camera_for, legend_for, vertex_areas};
use fissure::app::overlay::OffscreenOverlay;
use fissure::render::{Renderer, capture};
use fissure::sim::{FrameReport, Pipeline, SimState};

/// Image size of replay frames.
pub const FRAME_SIZE: (u32, u32) = (960, 720);

/// Renders frames of one pipeline offscreen.
pub struct OffscreenFrames {
    size: (u32, u32),
    renderer: Option<Renderer>,
    scene: Option<SceneStatic>,
    areas: Vec<f64>,
    snapshot: Snapshot,
    buffers: SceneBuffers,
    overlay: OffscreenOverlay,
    pub options: DrawOptions,
    pub view: ViewPreset,
}

impl OffscreenFrames {
    pub fn new(size: (u32, u32), options: DrawOptions, view: ViewPreset) -> Self {
        Self { size, renderer: None, scene: None, areas: Vec::new(), snapshot: Snapshot::default(), buffers: SceneBuffers::default(), overlay: OffscreenOverlay::default(), options, view }
    }

    /// Draws the current state of `pipeline` (`report`: the last step's, or default).
    pub fn render(&mut self, pipeline: &Pipeline, state: &SimState, report: &FrameReport) -> anyhow::Result<image::RgbaImage> {
        if self.renderer.is_none() {
            self.renderer = Some(Renderer::new_offscreen(self.size).context("starting the offscreen renderer")?);
        }
        if self.scene.is_none() {
            self.scene = Some(SceneStatic::of(pipeline));
            self.areas = vertex_areas(pipeline.rest_positions(), &pipeline.surface().triangles);
        }
        let (Some(renderer), Some(scene)) = (self.renderer.as_mut(), self.scene.as_ref()) else {
            anyhow::bail!("the offscreen renderer did not start");
        };
        self.snapshot.capture(pipeline, state, report, &self.areas);
        let camera = camera_for(self.view, pipeline, &state.poses, &self.options.views);
        let view = self.buffers.view(scene, &self.snapshot, &self.options, camera);
        renderer.render_offscreen(&view).context("rendering a frame")?;
        // The shown field's colour bar and the vessels' stretch legend, painted by the window's legend code.
        let legend = legend_for(&self.options, &self.snapshot);
        let vessels = scene.vessel_legend.as_ref();
        if legend.is_some() || vessels.is_some() {
            self.overlay
                .paint(renderer, |painter, rect| {
                    if let Some(legend) = &legend {
                        fissure::ui::legend::paint_legend(painter, rect, legend);
                    }
                    if let Some(vessels) = vessels {
                        fissure::ui::legend::paint_vessel_legend(painter, rect, vessels);
                    }
                })
                .context("drawing the colour legend")?;
        }
        capture::read_offscreen(renderer).context("reading the frame back")
    }
}

/// Writes one PNG a frame with a kept renderer.
pub struct FrameWriter {
    dir: PathBuf,
    frames: OffscreenFrames,
    report: FrameReport,
}

impl FrameWriter {
    pub fn new(out_dir: &Path) -> anyhow::Result<Self> {
        let dir = out_dir.join("frames");
        std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
        Ok(Self { dir, frames: OffscreenFrames::new(FRAME_SIZE, DrawOptions::default(), ViewPreset::Overview), report: FrameReport::default() })
    }

    pub fn write(&mut self, pipeline: &Pipeline, state: &SimState) -> anyhow::Result<()> {
        let image = self.frames.render(pipeline, state, &self.report)?;
        let path = self.dir.join(format!("frame_{:05}.png", state.frame.saturating_sub(1)));
        capture::save_png(&image, &path).with_context(|| format!("writing {}", path.display()))?;
        Ok(())
    }
}

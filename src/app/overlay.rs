//! egui shapes painted over an offscreen frame: `fissure screenshot` and
//! `replay --frames` draw the colour legend with the window's own code.
//!
//! In: a renderer with an offscreen target holding the drawn scene, and a
//! closure that paints with an egui painter over the whole image. Out: the
//! target with the shapes blended on top. Stays true: one egui pass, no
//! input (no layout pass needed: painters only); the egui renderer is made
//! once and kept; textures egui frees are freed.

use crate::render::{RenderError, Renderer};

/// A kept egui context and renderer for offscreen overlays.
#[derive(Default)]
pub struct OffscreenOverlay {
    ctx: egui::Context,
    renderer: Option<egui_wgpu::Renderer>,
}

impl OffscreenOverlay {
    /// Paints `paint(painter, image_rect)` over `renderer`'s offscreen target.
    pub fn paint(&mut self, renderer: &Renderer, paint: impl FnOnce(&egui::Painter, egui::Rect)) -> Result<(), RenderError> {
        let Some((target, (width, height))) = renderer.offscreen_target() else {
            return Err(RenderError::NoOffscreenTarget);
        };
        let device = renderer.device();
        let queue = renderer.queue();
        let egui_renderer = self.renderer.get_or_insert_with(|| {
            egui_wgpu::Renderer::new(device, renderer.color_format(), egui_wgpu::RendererOptions::default())
        });
        let screen = egui::Rect::from_min_size(egui::Pos2::ZERO, egui::vec2(width as f32, height as f32));
        let raw = egui::RawInput { screen_rect: Some(screen), ..egui::RawInput::default() };
        let mut paint = Some(paint);
        let mut out = self.ctx.run_ui(raw, |ui| {
            let painter = ui.ctx().layer_painter(egui::LayerId::new(egui::Order::Foreground, egui::Id::unique("offscreen_overlay")));
            if let Some(paint) = paint.take() {
                paint(&painter, screen);
            }
        });
        let jobs = self.ctx.tessellate(std::mem::take(&mut out.shapes), out.pixels_per_point);
        for (id, deltas) in &out.textures_delta.set {
            for delta in deltas.iter() {
                egui_renderer.update_texture(device, queue, *id, delta);
            }
        }
        let descriptor = egui_wgpu::ScreenDescriptor { size_in_pixels: [width, height], pixels_per_point: out.pixels_per_point };
        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("overlay encoder") });
        let extra = egui_pass(egui_renderer, device, queue, &mut encoder, target, &jobs, &descriptor);
        queue.submit(extra.into_iter().chain([encoder.finish()]));
        for id in &out.textures_delta.free {
            egui_renderer.free_texture(id);
        }
        out.textures_delta.clear(); // handled above (an unhandled delta panics on drop)
        Ok(())
    }
}

/// Uploads egui's buffers and draws `jobs` over `target` (loaded, not
/// cleared) in one render pass; returns the command buffers egui needs
/// submitted before `encoder`'s. The window and the offscreen overlay share it.
pub fn egui_pass(
    egui_renderer: &mut egui_wgpu::Renderer,
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    encoder: &mut wgpu::CommandEncoder,
    target: &wgpu::TextureView,
    jobs: &[egui::ClippedPrimitive],
    screen: &egui_wgpu::ScreenDescriptor,
) -> Vec<wgpu::CommandBuffer> {
    let extra = egui_renderer.update_buffers(device, queue, encoder, jobs, screen);
    let pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
        label: Some("egui pass"),
        color_attachments: &[Some(wgpu::RenderPassColorAttachment {
            view: target,
            resolve_target: None,
            depth_slice: None,
            ops: wgpu::Operations { load: wgpu::LoadOp::Load, store: wgpu::StoreOp::Store },
        })],
        depth_stencil_attachment: None,
        timestamp_writes: None,
        occlusion_query_set: None,
        multiview_mask: None,
    });
    let mut pass = pass.forget_lifetime();
    egui_renderer.render(&mut pass, jobs, screen);
    extra
}

//! The window-backed renderer: a [`Renderer`] drawing into a winit window's
//! wgpu surface, with room for egui to draw on top in the same encoder.
//!
//! In: an `Arc<winit::window::Window>`, its size on resize, a [`SceneView`]
//! per frame. Out: presented frames. Stays true: the present mode is chosen
//! explicitly (Fifo unless asked otherwise: Xvfb's default is Immediate); an
//! outdated or lost surface is reconfigured and the frame skipped, never a
//! panic; a zero-sized (minimised) window skips frames.

use super::RenderError;
use super::renderer::{Renderer, request_device};
use super::scene::SceneView;
use std::sync::Arc;

/// What happened to a frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FrameOutcome {
    /// Drawn and presented.
    Presented,
    /// Skipped (minimised, occluded, timeout, or the surface was reconfigured).
    Skipped,
}

/// A renderer bound to a window surface.
pub struct WindowRenderer {
    surface: wgpu::Surface<'static>,
    config: wgpu::SurfaceConfiguration,
    renderer: Renderer,
}

impl WindowRenderer {
    /// Creates the surface, adapter and device for `window`. `present_mode`
    /// `None` picks Fifo (vsync; always supported).
    pub fn new(
        window: Arc<winit::window::Window>,
        present_mode: Option<wgpu::PresentMode>,
    ) -> Result<Self, RenderError> {
        let instance =
            wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
        let size = window.inner_size();
        let surface = instance
            .create_surface(window)
            .map_err(|e| RenderError::Surface(e.to_string()))?;
        let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
            power_preference: wgpu::PowerPreference::HighPerformance,
            force_fallback_adapter: false,
            compatible_surface: Some(&surface),
            apply_limit_buckets: false,
        }))
        .map_err(|e| RenderError::NoAdapter(e.to_string()))?;
        let (device, queue) = request_device(&adapter)?;
        let caps = surface.get_capabilities(&adapter);
        let format = caps
            .formats
            .iter()
            .copied()
            .find(|f| f.is_srgb())
            .or_else(|| caps.formats.first().copied())
            .ok_or_else(|| {
                RenderError::Surface("the surface supports no format on this adapter".into())
            })?;
        let mut config = surface
            .get_default_config(&adapter, size.width.max(1), size.height.max(1))
            .ok_or_else(|| {
                RenderError::Surface("the surface is not supported by the adapter".into())
            })?;
        config.format = format;
        let wanted = present_mode.unwrap_or(wgpu::PresentMode::Fifo);
        config.present_mode = if caps.present_modes.contains(&wanted) {
            wanted
        } else {
            wgpu::PresentMode::Fifo
        };
        surface.configure(&device, &config);
        let msaa = adapter
            .get_texture_format_features(format)
            .flags
            .sample_count_supported(4);
        let mut renderer = Renderer::with_device(device, queue, format, if msaa { 4 } else { 1 })?;
        let info = adapter.get_info();
        renderer.name_adapter(&info);
        tracing::info!(adapter = %info.name, backend = ?info.backend, ?format, present_mode = ?config.present_mode, "window renderer ready");
        Ok(Self {
            surface,
            config,
            renderer,
        })
    }

    /// The inner renderer (device, queue, format for egui-wgpu).
    pub fn renderer(&self) -> &Renderer {
        &self.renderer
    }

    /// Current surface size, pixels.
    pub fn size(&self) -> (u32, u32) {
        (self.config.width, self.config.height)
    }

    /// Reconfigures after a window resize (a zero size is remembered and frames skip).
    pub fn resize(&mut self, width: u32, height: u32) {
        if width == 0 || height == 0 {
            self.config.width = 0;
            self.config.height = 0;
            return;
        }
        self.config.width = width;
        self.config.height = height;
        self.surface.configure(self.renderer.device(), &self.config);
    }

    /// Draws `view`, then lets `overlay` record more passes (e.g. egui) into the
    /// same encoder and target, then presents.
    pub fn render(
        &mut self,
        view: &SceneView,
        overlay: impl FnOnce(&wgpu::Device, &wgpu::Queue, &mut wgpu::CommandEncoder, &wgpu::TextureView),
    ) -> Result<FrameOutcome, RenderError> {
        if self.config.width == 0 || self.config.height == 0 {
            return Ok(FrameOutcome::Skipped);
        }
        let frame = match self.surface.get_current_texture() {
            wgpu::CurrentSurfaceTexture::Success(t)
            | wgpu::CurrentSurfaceTexture::Suboptimal(t) => t,
            wgpu::CurrentSurfaceTexture::Timeout | wgpu::CurrentSurfaceTexture::Occluded => {
                return Ok(FrameOutcome::Skipped);
            }
            wgpu::CurrentSurfaceTexture::Outdated | wgpu::CurrentSurfaceTexture::Lost => {
                self.surface.configure(self.renderer.device(), &self.config);
                return Ok(FrameOutcome::Skipped);
            }
            wgpu::CurrentSurfaceTexture::Validation => {
                return Err(RenderError::Surface(
                    "validation error acquiring the frame".into(),
                ));
            }
        };
        let target = frame.texture.create_view(&wgpu::TextureViewDescriptor {
            label: Some("surface frame view"),
            ..Default::default()
        });
        let size = (self.config.width, self.config.height);
        self.renderer.prepare(view, size)?;
        let device = self.renderer.device().clone();
        let queue = self.renderer.queue().clone();
        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("window frame encoder"),
        });
        self.renderer.encode(&mut encoder, &target);
        overlay(&device, &queue, &mut encoder, &target);
        queue.submit([encoder.finish()]);
        queue.present(frame);
        self.renderer.check_gpu_error()?;
        Ok(FrameOutcome::Presented)
    }
}

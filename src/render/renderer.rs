//! The wgpu renderer: draws a [`SceneView`] into a colour target.
//!
//! In: a [`SceneView`] per frame and a target (the offscreen texture of
//! [`Renderer::new_offscreen`], or a window's surface texture through
//! [`Renderer::with_device`]). Out: GPU commands; for offscreen, pixels via
//! [`super::capture`]. Stays true: buffers persist and grow only when a frame
//! needs more (per frame only positions, normals and colours are uploaded; the
//! index buffer is re-uploaded only when the triangle list changes); normals
//! are recomputed from the deformed positions every frame (area-weighted, CPU);
//! a wgpu validation error becomes a [`RenderError::Gpu`], never a panic.
//!
//! Passes, in order, in one render pass with a depth buffer and 4x MSAA where
//! the format allows: brain surface (two-sided), blades and opaque tether
//! tubes (vessels, torn ends' stubs), hidden contact (with a pressure field:
//! the triangles under pressure drawn again, translucent, only where something
//! nearer hides them, so the patch under a blade or behind a lip of tissue
//! shows through it), translucent strands (bands) and skull spheres (alpha
//! blended, no depth write), overlays (nodes as squares, pairs as ribbons; on
//! top, no depth test).

use super::RenderError;
use super::gpu_types::{Globals, Vertex};
use super::meshes;
use super::scene::SceneView;
use std::sync::{Arc, Mutex};

/// The depth buffer's format.
pub const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;
/// The offscreen colour format (sRGB: the shaders write linear colour).
pub const OFFSCREEN_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8UnormSrgb;

/// A GPU buffer that grows (to the next power of two) when a frame needs more.
struct GrowBuffer {
    buffer: wgpu::Buffer,
    capacity: u64,
    usage: wgpu::BufferUsages,
    label: &'static str,
}

impl GrowBuffer {
    fn new(device: &wgpu::Device, label: &'static str, usage: wgpu::BufferUsages) -> Self {
        let capacity = 4096;
        let buffer = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size: capacity,
            usage: usage | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        Self {
            buffer,
            capacity,
            usage,
            label,
        }
    }

    fn write(&mut self, device: &wgpu::Device, queue: &wgpu::Queue, bytes: &[u8]) {
        let needed = (bytes.len() as u64)
            .max(4)
            .next_multiple_of(wgpu::COPY_BUFFER_ALIGNMENT);
        if needed > self.capacity {
            self.capacity = needed.next_power_of_two();
            self.buffer = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(self.label),
                size: self.capacity,
                usage: self.usage | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
        }
        if !bytes.is_empty() {
            let aligned = bytes.len() - bytes.len() % wgpu::COPY_BUFFER_ALIGNMENT as usize;
            queue.write_buffer(&self.buffer, 0, &bytes[..aligned]);
            if aligned < bytes.len() {
                let mut tail = [0u8; 4];
                tail[..bytes.len() - aligned].copy_from_slice(&bytes[aligned..]);
                queue.write_buffer(&self.buffer, aligned as u64, &tail);
            }
        }
    }
}

/// Colour (MSAA) and depth attachments sized to the target.
struct Attachments {
    size: (u32, u32),
    msaa: Option<wgpu::TextureView>,
    depth: wgpu::TextureView,
}

/// The offscreen colour texture of a headless renderer.
pub(crate) struct OffscreenTarget {
    pub(crate) texture: wgpu::Texture,
    pub(crate) view: wgpu::TextureView,
    pub(crate) size: (u32, u32),
}

/// Ranges of the shared tool vertex buffer.
#[derive(Debug, Default, Clone, Copy)]
struct ToolRanges {
    /// Blades and opaque tether tubes.
    blades: (u32, u32),
    /// Translucent strands, then skull spheres.
    skull: (u32, u32),
    overlays: (u32, u32),
}

#[derive(Default)]
struct Scratch {
    normals: Vec<crate::math::Vec3>,
    contact: Vec<[u32; 3]>,
    surface: Vec<Vertex>,
    tools: Vec<Vertex>,
    unit_sphere: Vec<crate::math::Vec3>,
    /// A coarse unit sphere: the rounded ends of tether tubes.
    unit_cap: Vec<crate::math::Vec3>,
}

/// The renderer. Create once; call [`Renderer::render`] (or
/// [`Renderer::prepare`] + [`Renderer::encode`] to share an encoder with egui) each frame.
pub struct Renderer {
    device: wgpu::Device,
    queue: wgpu::Queue,
    adapter_name: String,
    color_format: wgpu::TextureFormat,
    sample_count: u32,
    globals: wgpu::Buffer,
    bind_group: wgpu::BindGroup,
    pipelines: Pipelines,
    buffers: SceneBuffers,
    background: wgpu::Color,
    attachments: Option<Attachments>,
    pub(crate) offscreen: Option<OffscreenTarget>,
    scratch: Scratch,
    gpu_error: Arc<Mutex<Option<String>>>,
}

/// The scene's render pipelines.
struct Pipelines {
    surface: wgpu::RenderPipeline,
    blade: wgpu::RenderPipeline,
    skull: wgpu::RenderPipeline,
    overlay: wgpu::RenderPipeline,
    hidden_contact: wgpu::RenderPipeline,
}

/// The frame's geometry on the GPU, and what it holds.
struct SceneBuffers {
    surface_vertices: GrowBuffer,
    surface_indices: GrowBuffer,
    /// The triangles under pressure (a pressure field only), for the hidden-contact pass.
    contact_indices: GrowBuffer,
    contact_index_count: u32,
    tool_vertices: GrowBuffer,
    index_count: u32,
    uploaded_triangles: Vec<[u32; 3]>,
    ranges: ToolRanges,
}

impl Pipelines {
    /// The scene's pipelines over the globals' `layout`, drawing into `color_format` with `sample_count` samples.
    fn new(device: &wgpu::Device, layout: &wgpu::BindGroupLayout, color_format: wgpu::TextureFormat, sample_count: u32) -> Self {
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("scene pipeline layout"),
            bind_group_layouts: &[Some(layout)],
            immediate_size: 0,
        });
        let surface_shader =
            device.create_shader_module(wgpu::include_wgsl!("../../shaders/surface.wgsl"));
        let tools_shader =
            device.create_shader_module(wgpu::include_wgsl!("../../shaders/tools.wgsl"));

        let make = |label: &'static str,
                    shader: &wgpu::ShaderModule,
                    fragment: &'static str,
                    topology: wgpu::PrimitiveTopology,
                    cull: Option<wgpu::Face>,
                    depth_write: bool,
                    depth_compare: wgpu::CompareFunction,
                    blend: Option<wgpu::BlendState>| {
            device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                label: Some(label),
                layout: Some(&pipeline_layout),
                vertex: wgpu::VertexState {
                    module: shader,
                    entry_point: Some("vs_main"),
                    compilation_options: Default::default(),
                    buffers: &[Some(Vertex::layout())],
                },
                primitive: wgpu::PrimitiveState {
                    topology,
                    cull_mode: cull,
                    front_face: wgpu::FrontFace::Ccw,
                    ..Default::default()
                },
                depth_stencil: Some(wgpu::DepthStencilState {
                    format: DEPTH_FORMAT,
                    depth_write_enabled: Some(depth_write),
                    depth_compare: Some(depth_compare),
                    stencil: Default::default(),
                    bias: Default::default(),
                }),
                multisample: wgpu::MultisampleState {
                    count: sample_count,
                    ..Default::default()
                },
                fragment: Some(wgpu::FragmentState {
                    module: shader,
                    entry_point: Some(fragment),
                    compilation_options: Default::default(),
                    targets: &[Some(wgpu::ColorTargetState {
                        format: color_format,
                        blend,
                        write_mask: wgpu::ColorWrites::ALL,
                    })],
                }),
                multiview_mask: None,
                cache: None,
            })
        };
        use wgpu::CompareFunction::{Always, Greater, Less};
        use wgpu::PrimitiveTopology::TriangleList;
        let surface = make("surface pipeline", &surface_shader, "fs_main", TriangleList, None, true, Less, None);
        let blade = make("blade pipeline", &tools_shader, "fs_lit", TriangleList, Some(wgpu::Face::Back), true, Less, None);
        let skull = make("skull pipeline", &tools_shader, "fs_lit", TriangleList, Some(wgpu::Face::Back), false, Less, Some(wgpu::BlendState::ALPHA_BLENDING));
        let hidden_contact = make("hidden contact pipeline", &surface_shader, "fs_hidden", TriangleList, None, false, Greater, Some(wgpu::BlendState::ALPHA_BLENDING));
        let overlay = make("overlay pipeline", &tools_shader, "fs_unlit", TriangleList, None, false, Always, None);
        Pipelines { surface, blade, skull, overlay, hidden_contact }
    }
}

/// Requests a headless device: honours `WGPU_BACKEND` (e.g. `vulkan`) and the
/// Vulkan driver chosen by `VK_DRIVER_FILES`. `Err(NoAdapter)` when none exists.
pub fn headless_device()
-> Result<(wgpu::Device, wgpu::Queue, wgpu::AdapterInfo, wgpu::Adapter), RenderError> {
    let instance =
        wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
    let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
        power_preference: wgpu::PowerPreference::HighPerformance,
        force_fallback_adapter: false,
        compatible_surface: None,
        apply_limit_buckets: false,
    }))
    .map_err(|e| RenderError::NoAdapter(e.to_string()))?;
    let info = adapter.get_info();
    let (device, queue) = request_device(&adapter)?;
    Ok((device, queue, info, adapter))
}

/// Requests a device with downlevel limits (enough for everything we draw).
pub fn request_device(adapter: &wgpu::Adapter) -> Result<(wgpu::Device, wgpu::Queue), RenderError> {
    let descriptor = wgpu::DeviceDescriptor {
        label: Some("fissure device"),
        required_limits: wgpu::Limits::downlevel_defaults().using_resolution(adapter.limits()),
        ..Default::default()
    };
    pollster::block_on(adapter.request_device(&descriptor))
        .map_err(|e| RenderError::Device(e.to_string()))
}

impl Renderer {
    /// A headless renderer drawing into its own `size` texture (width, height in
    /// pixels, each 1..=8192). `Err(NoAdapter)` when there is no GPU or driver.
    pub fn new_offscreen(size: (u32, u32)) -> Result<Self, RenderError> {
        check_size(size)?;
        let (device, queue, info, adapter) = headless_device()?;
        let msaa = adapter
            .get_texture_format_features(OFFSCREEN_FORMAT)
            .flags
            .sample_count_supported(4)
            && adapter
                .get_texture_format_features(DEPTH_FORMAT)
                .flags
                .sample_count_supported(4);
        let mut renderer =
            Self::with_device(device, queue, OFFSCREEN_FORMAT, if msaa { 4 } else { 1 })?;
        renderer.name_adapter(&info);
        renderer.resize_offscreen(size)?;
        tracing::info!(adapter = %renderer.adapter_name, msaa, "offscreen renderer ready");
        Ok(renderer)
    }

    /// A renderer on an existing device drawing into targets of `color_format`
    /// (for the window: the surface's format). `sample_count` 1 or 4.
    pub fn with_device(
        device: wgpu::Device,
        queue: wgpu::Queue,
        color_format: wgpu::TextureFormat,
        sample_count: u32,
    ) -> Result<Self, RenderError> {
        let gpu_error = Arc::new(Mutex::new(None::<String>));
        let sink = Arc::clone(&gpu_error);
        device.on_uncaptured_error(Arc::new(move |e: wgpu::Error| {
            tracing::error!(error = %e, "wgpu error");
            if let Ok(mut slot) = sink.lock() {
                slot.get_or_insert_with(|| e.to_string());
            }
        }));
        let sample_count = if sample_count >= 4 { 4 } else { 1 };
        let globals = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("globals uniform"),
            size: std::mem::size_of::<Globals>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("globals layout"),
            entries: &[wgpu::BindGroupLayoutEntry {
                binding: 0,
                visibility: wgpu::ShaderStages::VERTEX_FRAGMENT,
                ty: wgpu::BindingType::Buffer {
                    ty: wgpu::BufferBindingType::Uniform,
                    has_dynamic_offset: false,
                    min_binding_size: None,
                },
                count: None,
            }],
        });
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("globals bind group"),
            layout: &layout,
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: globals.as_entire_binding(),
            }],
        });
        let pipelines = Pipelines::new(&device, &layout, color_format, sample_count);
        let vertex_usage = wgpu::BufferUsages::VERTEX;
        let buffers = SceneBuffers {
            surface_vertices: GrowBuffer::new(&device, "surface vertices", vertex_usage),
            surface_indices: GrowBuffer::new(&device, "surface indices", wgpu::BufferUsages::INDEX),
            contact_indices: GrowBuffer::new(&device, "contact indices", wgpu::BufferUsages::INDEX),
            contact_index_count: 0,
            tool_vertices: GrowBuffer::new(&device, "tool vertices", vertex_usage),
            index_count: 0,
            uploaded_triangles: Vec::new(),
            ranges: ToolRanges::default(),
        };
        let scratch = Scratch {
            unit_sphere: meshes::unit_sphere(24, 48),
            unit_cap: meshes::unit_sphere(4, meshes::TUBE_SIDES),
            ..Scratch::default()
        };
        let renderer = Self {
            device,
            queue,
            adapter_name: String::new(),
            color_format,
            sample_count,
            globals,
            bind_group,
            pipelines,
            buffers,
            background: wgpu::Color::BLACK,
            attachments: None,
            offscreen: None,
            scratch,
            gpu_error,
        };
        renderer.take_gpu_error()?;
        Ok(renderer)
    }

    /// The wgpu device (for egui-wgpu and the window's surface).
    pub fn device(&self) -> &wgpu::Device {
        &self.device
    }

    /// The wgpu queue.
    pub fn queue(&self) -> &wgpu::Queue {
        &self.queue
    }

    /// The colour format the pipelines target.
    pub fn color_format(&self) -> wgpu::TextureFormat {
        self.color_format
    }

    /// MSAA sample count (1 or 4).
    pub fn sample_count(&self) -> u32 {
        self.sample_count
    }

    /// Records the adapter's name and backend (the offscreen and the window's renderer do; a renderer on a
    /// device from elsewhere stays unnamed).
    pub(crate) fn name_adapter(&mut self, info: &wgpu::AdapterInfo) {
        self.adapter_name = format!("{} ({:?})", info.name, info.backend);
    }

    /// The adapter drawing, as "NAME (BACKEND)".
    pub fn adapter_name(&self) -> &str {
        &self.adapter_name
    }

    fn take_gpu_error(&self) -> Result<(), RenderError> {
        match self.gpu_error.lock().map(|mut e| e.take()) {
            Ok(Some(message)) => Err(RenderError::Gpu(message)),
            _ => Ok(()),
        }
    }

    /// Resizes (or creates) the offscreen target.
    pub fn resize_offscreen(&mut self, size: (u32, u32)) -> Result<(), RenderError> {
        check_size(size)?;
        if self.offscreen.as_ref().is_some_and(|o| o.size == size) {
            return Ok(());
        }
        let texture = self.device.create_texture(&wgpu::TextureDescriptor {
            label: Some("offscreen colour"),
            size: wgpu::Extent3d {
                width: size.0,
                height: size.1,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: self.color_format,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
            view_formats: &[],
        });
        let view = texture.create_view(&wgpu::TextureViewDescriptor {
            label: Some("offscreen colour view"),
            ..Default::default()
        });
        self.offscreen = Some(OffscreenTarget {
            texture,
            view,
            size,
        });
        Ok(())
    }

    fn ensure_attachments(&mut self, size: (u32, u32)) {
        if self.attachments.as_ref().is_some_and(|a| a.size == size) {
            return;
        }
        let extent = wgpu::Extent3d {
            width: size.0,
            height: size.1,
            depth_or_array_layers: 1,
        };
        let make = |label: &'static str, format: wgpu::TextureFormat| {
            self.device
                .create_texture(&wgpu::TextureDescriptor {
                    label: Some(label),
                    size: extent,
                    mip_level_count: 1,
                    sample_count: self.sample_count,
                    dimension: wgpu::TextureDimension::D2,
                    format,
                    usage: wgpu::TextureUsages::RENDER_ATTACHMENT,
                    view_formats: &[],
                })
                .create_view(&wgpu::TextureViewDescriptor {
                    label: Some(label),
                    ..Default::default()
                })
        };
        let msaa = (self.sample_count > 1).then(|| make("msaa colour", self.color_format));
        let depth = make("depth", DEPTH_FORMAT);
        self.attachments = Some(Attachments { size, msaa, depth });
    }

    /// Validates `view` and uploads this frame's data for a target of `size`.
    pub fn prepare(&mut self, view: &SceneView, size: (u32, u32)) -> Result<(), RenderError> {
        check_size(size)?;
        let surface = &view.surface;
        let count = surface.positions.len();
        if let Some(field) = &surface.field
            && field.values.len() != count
        {
            return Err(RenderError::FieldLength {
                values: field.values.len(),
                vertices: count,
            });
        }
        self.upload_triangles(surface.triangles, count)?;
        let cam = &view.camera;
        if !(cam.target.iter().all(|c| c.is_finite())
            && cam.distance_m.is_finite()
            && cam.distance_m > 0.0)
        {
            return Err(RenderError::Camera);
        }
        let origin = cam.target;
        let s = &mut self.scratch;
        meshes::surface_vertices(surface, &origin, &mut s.normals, &mut s.surface);
        self.buffers.surface_vertices
            .write(&self.device, &self.queue, bytemuck::cast_slice(&s.surface));
        meshes::pressed_triangles(surface.triangles, &s.surface, &mut s.contact);
        if !s.contact.is_empty() {
            self.buffers.contact_indices
                .write(&self.device, &self.queue, bytemuck::cast_slice(&s.contact));
        }
        self.buffers.contact_index_count = (s.contact.len() * 3) as u32;
        self.upload_tools(view);
        self.upload_globals(view, size);
        let [r, g, b] = view.background.map(|c| {
            if c.is_finite() {
                c.clamp(0.0, 1.0) as f64
            } else {
                0.0
            }
        });
        self.background = wgpu::Color { r, g, b, a: 1.0 };
        self.ensure_attachments(size);
        Ok(())
    }

    /// Uploads the surface's triangles where they changed, each index checked against the `count` vertices.
    fn upload_triangles(&mut self, triangles: &[[u32; 3]], count: usize) -> Result<(), RenderError> {
        let out_of_range = triangles.iter().enumerate().find_map(|(k, t)| t.iter().find(|&&i| i as usize >= count).map(|&i| (k, i)));
        if let Some((triangle, index)) = out_of_range {
            return Err(RenderError::TriangleIndex { triangle, index, vertices: count });
        }
        if triangles != self.buffers.uploaded_triangles.as_slice() {
            self.buffers.surface_indices.write(&self.device, &self.queue, bytemuck::cast_slice(triangles));
            self.buffers.uploaded_triangles.clear();
            self.buffers.uploaded_triangles.extend_from_slice(triangles);
            self.buffers.index_count = (triangles.len() * 3) as u32;
        }
        Ok(())
    }

    /// The blades, the tethers, the skull spheres and the overlays, one vertex buffer with their ranges.
    fn upload_tools(&mut self, view: &SceneView) {
        let cam = &view.camera;
        let origin = cam.target;
        let s = &mut self.scratch;
        s.tools.clear();
        meshes::blade_vertices(view.spatulas, &origin, &mut s.tools);
        meshes::tube_vertices(view.tethers, true, &s.unit_cap, &origin, &mut s.tools);
        let blades_end = s.tools.len() as u32;
        meshes::tube_vertices(view.tethers, false, &s.unit_cap, &origin, &mut s.tools);
        meshes::sphere_vertices(view.skull, &s.unit_sphere, &origin, &mut s.tools);
        let skull_end = s.tools.len() as u32;
        let (right, up) = cam.right_up();
        meshes::overlay_vertices(
            &view.overlays,
            &origin,
            &right,
            &up,
            cam.distance_m * 0.006,
            &mut s.tools,
        );
        let overlays_end = s.tools.len() as u32;
        self.buffers.ranges = ToolRanges {
            blades: (0, blades_end),
            skull: (blades_end, skull_end),
            overlays: (skull_end, overlays_end),
        };
        self.buffers.tool_vertices
            .write(&self.device, &self.queue, bytemuck::cast_slice(&s.tools));

    }

    /// The camera, the eye and the key light.
    fn upload_globals(&mut self, view: &SceneView, size: (u32, u32)) {
        let cam = &view.camera;
        let aspect = size.0 as f64 / size.1 as f64;
        let m = cam.view_projection(aspect);
        let mut view_proj = [[0f32; 4]; 4];
        for (c, col) in view_proj.iter_mut().enumerate() {
            for (r, x) in col.iter_mut().enumerate() {
                *x = m[(r, c)] as f32;
            }
        }
        let eye = cam.back_direction() * cam.distance_m;
        let (right, up) = cam.right_up();
        // Key light: above, to the right of and behind the eye.
        let light = (cam.back_direction() * 0.8 + up * 0.9 + right * 0.4).normalize();
        let globals = Globals {
            view_proj,
            eye: [eye.x as f32, eye.y as f32, eye.z as f32, 0.0],
            light_dir: [light.x as f32, light.y as f32, light.z as f32, 0.0],
            // w: the plain brain is wet (a coaxial highlight, the microscope's light); a field is shown matte.
            params: [0.15, 0.08, 32.0, if view.surface.field.is_none() { 1.0 } else { 0.0 }],
        };
        self.queue
            .write_buffer(&self.globals, 0, bytemuck::bytes_of(&globals));
    }

    /// Records the scene pass into `encoder`, drawing into `target` (a view of a
    /// texture of the size given to [`Renderer::prepare`] and of
    /// [`Renderer::color_format`]).
    pub fn encode(&self, encoder: &mut wgpu::CommandEncoder, target: &wgpu::TextureView) {
        let Some(att) = self.attachments.as_ref() else {
            return;
        };
        let (view, resolve_target, store) = match &att.msaa {
            Some(msaa) => (msaa, Some(target), wgpu::StoreOp::Discard),
            None => (target, None, wgpu::StoreOp::Store),
        };
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("scene pass"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view,
                depth_slice: None,
                resolve_target,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(self.background),
                    store,
                },
            })],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &att.depth,
                depth_ops: Some(wgpu::Operations {
                    load: wgpu::LoadOp::Clear(1.0),
                    store: wgpu::StoreOp::Discard,
                }),
                stencil_ops: None,
            }),
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        pass.set_bind_group(0, &self.bind_group, &[]);
        // Surface triangles (`indices`, `count` indices) with `pipeline`.
        let surface = |pass: &mut wgpu::RenderPass<'_>, pipeline, indices: &GrowBuffer, count: u32| {
            if count > 0 {
                pass.set_pipeline(pipeline);
                pass.set_vertex_buffer(0, self.buffers.surface_vertices.buffer.slice(..));
                pass.set_index_buffer(indices.buffer.slice(..), wgpu::IndexFormat::Uint32);
                pass.draw_indexed(0..count, 0, 0..1);
            }
        };
        surface(&mut pass, &self.pipelines.surface, &self.buffers.surface_indices, self.buffers.index_count);
        pass.set_vertex_buffer(0, self.buffers.tool_vertices.buffer.slice(..));
        let r = self.buffers.ranges;
        if r.blades.1 > r.blades.0 {
            pass.set_pipeline(&self.pipelines.blade);
            pass.draw(r.blades.0..r.blades.1, 0..1);
        }
        // After everything opaque, so the depth buffer knows what hides the patch.
        if self.buffers.contact_index_count > 0 {
            surface(&mut pass, &self.pipelines.hidden_contact, &self.buffers.contact_indices, self.buffers.contact_index_count);
            pass.set_vertex_buffer(0, self.buffers.tool_vertices.buffer.slice(..));
        }
        for (pipeline, (start, end)) in [
            (&self.pipelines.skull, r.skull),
            (&self.pipelines.overlay, r.overlays),
        ] {
            if end > start {
                pass.set_pipeline(pipeline);
                pass.draw(start..end, 0..1);
            }
        }
    }

    /// Prepares, encodes and submits one frame into `target` of `size`.
    pub fn render(
        &mut self,
        view: &SceneView,
        target: &wgpu::TextureView,
        size: (u32, u32),
    ) -> Result<(), RenderError> {
        self.prepare(view, size)?;
        let mut encoder = self
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("scene encoder"),
            });
        self.encode(&mut encoder, target);
        self.queue.submit([encoder.finish()]);
        self.take_gpu_error()
    }

    /// Renders into the offscreen target (see [`Renderer::new_offscreen`]).
    pub fn render_offscreen(&mut self, view: &SceneView) -> Result<(), RenderError> {
        let (target, size) = match &self.offscreen {
            Some(o) => (o.view.clone(), o.size),
            None => return Err(RenderError::NoOffscreenTarget),
        };
        self.render(view, &target, size)
    }

    /// The offscreen target's view and size (for overlays painted after the scene).
    pub fn offscreen_target(&self) -> Option<(&wgpu::TextureView, (u32, u32))> {
        self.offscreen.as_ref().map(|o| (&o.view, o.size))
    }

    pub(crate) fn check_gpu_error(&self) -> Result<(), RenderError> {
        self.take_gpu_error()
    }
}

fn check_size(size: (u32, u32)) -> Result<(), RenderError> {
    if size.0 == 0 || size.1 == 0 || size.0 > 8192 || size.1 > 8192 {
        return Err(RenderError::Size {
            width: size.0,
            height: size.1,
        });
    }
    Ok(())
}

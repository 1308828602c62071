//! GPU backend: one WGSL compute pass (`shaders/collision.wgsl`) tests every ray
//! against every triangle in f32 (the paper's GPGPU method), all spatulas and faces
//! in one dispatch; results come back through a staging buffer.
//!
//! In: triangles (uploaded once), positions per frame, rays per frame. Out: nearest
//! hits per ray (t, u, v widened to f64). Stays true:
//! - Persistent buffers: positions, triangles, rays, results and staging are made
//!   once (rays/results sized for the stage's node count); per frame only the
//!   vertices whose f32 value changed are written, in runs (gaps of up to
//!   `RUN_GAP` unchanged vertices are bridged); when more than half changed, the
//!   whole buffer is written in one call. [`GpuCaster::last_upload`] says which.
//! - Coordinates are made relative to the centre of the rest surface's bounding
//!   box before the f32 conversion (absolute error about 6e-8 of the model size).
//! - Agreement with the f64 backends: the same triangles are found except where
//!   the f64 answer is a near-tie: a hit whose barycentrics (u, v, 1-u-v) lie within
//!   `tolerance` of 0 (an edge or vertex, where f32 may pick the neighbour), or two
//!   hits on one side within `tolerance` x model size in t. `tests/collision_backends.rs`
//!   checks exactly this with tolerance 1e-5.
//! - No adapter, no device, or a failed pipeline: `GpuCaster::new` returns an error
//!   (the stage then falls back to `bvh` with a warning); nothing panics.

use super::{CONTACT_TOLERANCE_RELATIVE, LineAccumulator, PairHits, PairLine, RayCaster, TriangleHit};
use crate::collision::{BackendKind, CollisionError};
use crate::math::Vec3;
use bytemuck::{Pod, Zeroable};

/// Unchanged vertices bridged inside one upload run.
const RUN_GAP: usize = 16;
const NO_HIT: u32 = u32::MAX;
const WORKGROUP: u32 = 64;

#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
struct GpuParams {
    ray_count: u32,
    triangle_count: u32,
    _pad: [u32; 2],
}

#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
struct GpuRay {
    origin: [f32; 4],
    direction: [f32; 4],
}

#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable, PartialEq)]
struct GpuSlot {
    triangle: u32,
    t: f32,
    u: f32,
    v: f32,
}

/// a: face 0 behind, b: face 0 front, c: face 1 behind, d: face 1 front (line parameter t).
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable, PartialEq)]
struct GpuHits {
    a: GpuSlot,
    b: GpuSlot,
    c: GpuSlot,
    d: GpuSlot,
}

/// How the last frame's positions went up.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct UploadStats {
    /// Vertices whose f32 value changed.
    pub changed_vertices: usize,
    /// Vertices written (changed ones plus bridged gaps, or all).
    pub written_vertices: usize,
    /// `write_buffer` calls made.
    pub writes: usize,
    /// True when the whole buffer was written at once.
    pub whole_buffer: bool,
}

/// The compute pass and its persistent resources.
pub struct GpuCaster {
    device: wgpu::Device,
    queue: wgpu::Queue,
    pipeline: wgpu::ComputePipeline,
    bind_group: wgpu::BindGroup,
    params: wgpu::Buffer,
    positions: wgpu::Buffer,
    rays: wgpu::Buffer,
    results: wgpu::Buffer,
    staging: wgpu::Buffer,
    centre: Vec3,
    triangle_count: u32,
    ray_capacity: usize,
    uploaded: Vec<[f32; 4]>,
    fresh: Vec<[f32; 4]>,
    gpu_rays: Vec<GpuRay>,
    adapter_name: String,
    last_upload: UploadStats,
}

fn to_f32(p: &Vec3, centre: &Vec3) -> [f32; 4] {
    let r = p - centre;
    [r.x as f32, r.y as f32, r.z as f32, 0.0]
}

fn gpu_err(what: &str, e: impl std::fmt::Display) -> CollisionError {
    CollisionError::Gpu(format!("{what}: {e}"))
}

impl GpuCaster {
    /// Creates device, pipeline and buffers for `triangles` at `positions` and up to
    /// `ray_capacity` rays a frame. Errors when no adapter or device is available.
    pub fn new(triangles: &[[u32; 3]], positions: &[Vec3], ray_capacity: usize) -> Result<Self, CollisionError> {
        use wgpu::util::DeviceExt;
        let instance = wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
        let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
            power_preference: wgpu::PowerPreference::HighPerformance,
            ..Default::default()
        }))
        .map_err(|e| gpu_err("no adapter", e))?;
        let limits = adapter.limits();
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("collision device"),
            required_limits: limits.clone(),
            ..Default::default()
        }))
        .map_err(|e| gpu_err("no device", e))?;
        let adapter_name = adapter.get_info().name;

        let (mut lo, mut hi) = (Vec3::repeat(f64::INFINITY), Vec3::repeat(f64::NEG_INFINITY));
        for p in positions {
            lo = lo.inf(p);
            hi = hi.sup(p);
        }
        let centre = if positions.is_empty() { Vec3::zeros() } else { (lo + hi) * 0.5 };
        let uploaded: Vec<[f32; 4]> = positions.iter().map(|p| to_f32(p, &centre)).collect();
        let tri4: Vec<[u32; 4]> = triangles.iter().map(|t| [t[0], t[1], t[2], 0]).collect();
        let ray_capacity = ray_capacity.max(1);
        let max_binding = limits.max_storage_buffer_binding_size as u64;
        let need = (uploaded.len().max(tri4.len()) * 16).max(ray_capacity * std::mem::size_of::<GpuHits>()) as u64;
        if need > max_binding {
            return Err(CollisionError::Gpu(format!("a buffer of {need} bytes exceeds the adapter's binding limit {max_binding}")));
        }

        let shader = device.create_shader_module(wgpu::include_wgsl!("../../../shaders/collision.wgsl"));
        let params = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("collision params"),
            size: std::mem::size_of::<GpuParams>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let positions_buf = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("collision positions"),
            contents: bytemuck::cast_slice(&uploaded),
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
        });
        let triangles_buf = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("collision triangles"),
            contents: bytemuck::cast_slice(&tri4),
            usage: wgpu::BufferUsages::STORAGE,
        });
        let rays = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("collision rays"),
            size: (ray_capacity * std::mem::size_of::<GpuRay>()) as u64,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let results_size = (ray_capacity * std::mem::size_of::<GpuHits>()) as u64;
        let results = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("collision results"),
            size: results_size,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let staging = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("collision staging"),
            size: results_size,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("collision pipeline"),
            layout: None,
            module: &shader,
            entry_point: Some("main"),
            compilation_options: Default::default(),
            cache: None,
        });
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("collision bind group"),
            layout: &pipeline.get_bind_group_layout(0),
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: params.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 1, resource: positions_buf.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 2, resource: triangles_buf.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 3, resource: rays.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 4, resource: results.as_entire_binding() },
            ],
        });
        Ok(Self {
            device,
            queue,
            pipeline,
            bind_group,
            params,
            positions: positions_buf,
            rays,
            results,
            staging,
            centre,
            triangle_count: triangles.len() as u32,
            ray_capacity,
            fresh: uploaded.clone(),
            uploaded,
            gpu_rays: Vec::with_capacity(ray_capacity),
            adapter_name,
            last_upload: UploadStats::default(),
        })
    }

    /// The adapter's name (e.g. "llvmpipe" for Mesa lavapipe).
    pub fn adapter_name(&self) -> &str {
        &self.adapter_name
    }

    /// How the last [`RayCaster::update_surface`] uploaded positions.
    pub fn last_upload(&self) -> UploadStats {
        self.last_upload
    }
}

impl RayCaster for GpuCaster {
    fn kind(&self) -> BackendKind {
        BackendKind::Gpu
    }

    fn update_surface(&mut self, positions: &[Vec3]) -> Result<(), CollisionError> {
        if positions.len() != self.uploaded.len() {
            return Err(CollisionError::VertexCount { expected: self.uploaded.len(), got: positions.len() });
        }
        let mut changed = 0;
        for (f, p) in self.fresh.iter_mut().zip(positions) {
            *f = to_f32(p, &self.centre);
        }
        for (f, u) in self.fresh.iter().zip(&self.uploaded) {
            changed += (f != u) as usize;
        }
        let mut stats = UploadStats { changed_vertices: changed, ..Default::default() };
        if changed * 2 > self.fresh.len() {
            self.queue.write_buffer(&self.positions, 0, bytemuck::cast_slice(&self.fresh));
            stats.whole_buffer = true;
            stats.writes = 1;
            stats.written_vertices = self.fresh.len();
        } else if changed > 0 {
            let n = self.fresh.len();
            let mut i = 0;
            while i < n {
                if self.fresh[i] == self.uploaded[i] {
                    i += 1;
                    continue;
                }
                // A run from i to the last changed vertex, bridging short gaps.
                let start = i;
                let mut end = i + 1;
                let mut j = i + 1;
                while j < n && j - end <= RUN_GAP {
                    if self.fresh[j] != self.uploaded[j] {
                        end = j + 1;
                    }
                    j += 1;
                }
                self.queue.write_buffer(&self.positions, (start * 16) as u64, bytemuck::cast_slice(&self.fresh[start..end]));
                stats.writes += 1;
                stats.written_vertices += end - start;
                i = end;
            }
        }
        std::mem::swap(&mut self.uploaded, &mut self.fresh);
        self.last_upload = stats;
        Ok(())
    }

    fn cast(&mut self, rays: &[PairLine], out: &mut Vec<PairHits>) -> Result<(), CollisionError> {
        out.clear();
        if rays.is_empty() {
            return Ok(());
        }
        if rays.len() > self.ray_capacity {
            return Err(CollisionError::Gpu(format!("{} rays exceed the capacity {}", rays.len(), self.ray_capacity)));
        }
        self.gpu_rays.clear();
        self.gpu_rays.extend(rays.iter().map(|r| GpuRay {
            origin: {
                let mut o = to_f32(&r.origin, &self.centre);
                o[3] = r.thickness as f32;
                o
            },
            direction: [r.direction.x as f32, r.direction.y as f32, r.direction.z as f32, (CONTACT_TOLERANCE_RELATIVE * r.thickness) as f32],
        }));
        let params = GpuParams { ray_count: rays.len() as u32, triangle_count: self.triangle_count, _pad: [0; 2] };
        self.queue.write_buffer(&self.params, 0, bytemuck::bytes_of(&params));
        self.queue.write_buffer(&self.rays, 0, bytemuck::cast_slice(&self.gpu_rays));
        let bytes = (rays.len() * std::mem::size_of::<GpuHits>()) as u64;
        let mut encoder = self.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("collision encoder") });
        {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some("collision pass"), timestamp_writes: None });
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, &self.bind_group, &[]);
            pass.dispatch_workgroups((rays.len() as u32).div_ceil(WORKGROUP), 1, 1);
        }
        encoder.copy_buffer_to_buffer(&self.results, 0, &self.staging, 0, bytes);
        self.queue.submit(Some(encoder.finish()));
        let (tx, rx) = std::sync::mpsc::channel();
        self.staging.map_async(wgpu::MapMode::Read, 0..bytes, move |r| {
            let _ = tx.send(r);
        });
        self.device.poll(wgpu::PollType::wait_indefinitely()).map_err(|e| gpu_err("poll", e))?;
        rx.recv().map_err(|e| gpu_err("readback", e))?.map_err(|e| gpu_err("map", e))?;
        {
            let view = self.staging.get_mapped_range(0..bytes).map_err(|e| gpu_err("mapped range", e))?;
            let hits: &[GpuHits] = bytemuck::cast_slice(&view);
            out.extend(hits.iter().zip(rays).map(|(h, line)| {
                // Re-offer the four f32 answers to the f64 accumulator: same thresholds,
                // t of face 1 re-expressed exactly as on the CPU.
                let mut acc = LineAccumulator::new(line.thickness);
                for s in [h.a, h.b, h.c, h.d] {
                    if s.triangle != NO_HIT && s.t.is_finite() && s.u.is_finite() && s.v.is_finite() {
                        acc.offer(TriangleHit { triangle: s.triangle, t: s.t as f64, u: s.u as f64, v: s.v as f64 });
                    }
                }
                acc.finish()
            }));
        }
        self.staging.unmap();
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pod_twins_match_the_wgsl_layout() {
        assert_eq!(std::mem::size_of::<GpuParams>(), 16, "Params is 4 x u32 in the shader");
        assert_eq!(std::mem::size_of::<GpuRay>(), 32, "Ray is two vec4<f32> in the shader");
        assert_eq!(std::mem::size_of::<GpuHits>(), 64, "Hits is four (u32, f32, f32, f32) slots in the shader");
    }
}

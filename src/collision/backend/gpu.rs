//! GPU backend: the BVH of `bvh.rs`, refit and traversed on the device, with every
//! answer decided in f64 on the CPU, so it returns the `reference` and `bvh` answers
//! bit for bit.
//!
//! One frame is ONE submission: the changed vertex positions and the lines go up,
//! the tree's boxes are refit bottom-up (`shaders/collision_refit.wgsl`, one dispatch
//! per tree level, leaves first), then one thread per pair line walks the tree
//! near-first (`shaders/collision.wgsl`) and writes, for each of the line's four
//! nearest-hit slots, up to three candidate triangle ids and a flag word: 52 bytes a
//! line come back, never a t or a barycentric. The CPU then tests each line's
//! candidates with the f64 watertight test of the other backends
//! ([`LineQuery::intersect`]) and offers the hits to the same [`LineAccumulator`];
//! a candidate that the f64 test misses brings in every triangle around its three
//! vertices (the f64 test then hits the neighbour the f32 test could not tell apart).
//! A flagged line is cast on the CPU by a [`BvhCaster`] refit only in frames that
//! have one.
//!
//! Why that gives the f64 answer (the shader's header has the slot rules): every
//! f32 hit that is not flagged as grazing has `|t32 - t64| <= w/8`, where the window
//! `w` = [`WINDOW_ULPS`] f32 ulps of the largest coordinate; the shader keeps the
//! best four hits of each slot with thresholds widened by `w`, returns the best three
//! and flags the line when the f64 winner could be outside them (a cluster of four
//! within `w`, a grazing hit inside the needed interval, a stack overflow). Only a
//! SURE f32 hit (every edge function beyond its error bound, so the f64 test hits it
//! too) bounds a slot and the needed interval: a near miss, e.g. a line passing
//! within rounding outside a silhouette edge, is a candidate but proves no hit, and
//! bounding with it pruned the true hit farther along the line. Pruning
//! is conservative: leaf boxes are grown by `w/2` of the surface's own scale. `tests/suite/collision_backends.rs`
//! checks bit-for-bit equality with `reference` on spheres, fissures, contact
//! configurations and the real brain surfaces.
//!
//! Latency: the frame's next stages need the hits, so the CPU waits for the map;
//! nothing is pipelined across frames (that would change answers). While the GPU
//! works, the CPU refits its own tree for the flagged lines (when the last frame
//! had some), so that refit costs no wait. Persistent buffers; per frame only
//! vertices whose f32 value changed are written, in runs (gaps of up to `RUN_GAP`
//! unchanged vertices are bridged; past `MAX_WRITES` runs, one span from the first
//! to the last); when more than half changed, the whole buffer is written at once
//! ([`GpuCaster::last_upload`]).
//! Timestamp queries, where the adapter has them, split the GPU time into refit and
//! traversal ([`GpuCaster::last_timings`]).
//!
//! Failure: no adapter, a tree too deep for the shader's stack or buffers past the
//! adapter's limits make [`GpuCaster::new`] an error; a lost device, a validation
//! error or a failed map make `cast` an error (the stage then switches to `bvh` for
//! the rest of the run, see `collision/mod.rs`). Nothing panics.

use super::bvh::{BvhCaster, TreeLayout};
use super::{LineAccumulator, PairHits, PairLine, RayCaster, TriangleHit};
use crate::collision::{BackendKind, CollisionError};
use crate::geometry::LineQuery;
use crate::math::Vec3;
use bytemuck::{Pod, Zeroable};
use std::sync::{Arc, Mutex};
use std::time::Instant;

/// Unchanged vertices bridged inside one upload run.
const RUN_GAP: usize = 16;
/// Most `write_buffer` calls a frame's positions take; past it one span goes up
/// (`fissure bench collision`: hundreds of scattered runs cost more than the span).
const MAX_WRITES: usize = 8;
const NO_HIT: u32 = u32::MAX;
const WORKGROUP: u32 = 64;
/// u32 words a line returns: 12 candidate ids and a flag word.
const OUT_STRIDE: usize = 13;
/// The shader's traversal stack (entries).
const SHADER_STACK: usize = 64;
/// The window `w` in f32 ulps (2^-23) of the largest coordinate: 32768 ulps is
/// 1/256 of it (0.3 mm on a brain 16 cm across). Hits whose f32 error bound passes
/// `w/8` are treated as grazing. Measured with `fissure bench collision`: at 8192
/// ulps 4-8 % of the brains' lines went to the CPU as grazing, at 32768 under 1 %,
/// for about 15 % more traversal (wider windows prune less).
const WINDOW_ULPS: f64 = 32768.0;
/// An origin farther than this many times the surface's extent from its centre is
/// cast on the CPU (the shader's error bounds assume comparable magnitudes).
const FAR_ORIGIN: f64 = 64.0;
/// Lines per parallel decision task.
const LINES_PER_TASK: usize = 64;
/// Flag bit the CPU adds for a line whose origin is farther than [`FAR_ORIGIN`].
const FAR_FLAG: u32 = 8;

thread_local! {
    /// Candidate set of one line's f64 decision, reused across lines and frames.
    static SEEN: std::cell::RefCell<Vec<u32>> = const { std::cell::RefCell::new(Vec::new()) };
}

#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
struct GpuParams {
    line_count: u32,
    _pad: [u32; 3],
    window: f32,
    coord_scale: f32,
    _pad2: [f32; 2],
}

#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
struct GpuLevel {
    start: u32,
    count: u32,
    margin: f32,
    _pad: u32,
}

#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
struct GpuRay {
    origin: [f32; 4],
    direction: [f32; 4],
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

/// Where the last `cast` spent its time, seconds.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct GpuTimings {
    /// CPU: positions and lines written to the queue (staging copies).
    pub upload: f64,
    /// CPU: from the submission until the results were mapped (GPU work plus transfers).
    pub wait: f64,
    /// CPU: candidates decided in f64, flagged lines cast on the CPU.
    pub decide: f64,
    /// GPU timestamps of the refit pass (None: the adapter has no timestamp queries).
    pub refit_gpu: Option<f64>,
    /// GPU timestamps of the traversal pass.
    pub traverse_gpu: Option<f64>,
    /// Lines the shader flagged (cast on the CPU).
    pub flagged_lines: usize,
    /// Flagged lines by reason: a cluster of four hits within the window, a grazing
    /// hit inside the needed interval, a full traversal stack (a line may have several).
    pub flag_reasons: [usize; 3],
    /// Lines in the frame.
    pub lines: usize,
}

/// Timestamp queries: 4 (refit begin/end, traversal begin/end), read back in the
/// first [`STAMP_BYTES`] of the results' staging buffer.
struct Timestamps {
    set: wgpu::QuerySet,
    resolve: wgpu::Buffer,
    period_ns: f64,
}

/// Bytes of the staging buffer before the results: the four timestamps.
const STAMP_BYTES: u64 = 32;

/// The device passes and their persistent resources.
pub struct GpuCaster {
    device: wgpu::Device,
    queue: wgpu::Queue,
    kernels: Kernels,
    buffers: FrameBuffers,
    timestamps: Option<Timestamps>,
    /// Uncaptured device errors and device loss, reported by wgpu's callbacks.
    fault: Arc<Mutex<Option<String>>>,
    scale: Scales,
    ray_capacity: usize,
    scratch: Scratch,
    surface: CpuSurface,
    cpu: ExactLines,
    adapter_name: String,
    last_upload: UploadStats,
    last_timings: GpuTimings,
    /// Test hook: the next cast fails as if the device were lost.
    fail_next: bool,
}

/// The refit and traversal kernels, their bind groups and the tree's levels.
struct Kernels {
    refit_pipeline: wgpu::ComputePipeline,
    traverse_pipeline: wgpu::ComputePipeline,
    refit_groups: Vec<wgpu::BindGroup>,
    traverse_group: wgpu::BindGroup,
    levels_buf: wgpu::Buffer,
    /// (start, count) of each level in `level_nodes`.
    levels: Vec<(u32, u32)>,
    level_stride: u64,
}

/// The buffers a frame writes and reads back.
struct FrameBuffers {
    params: wgpu::Buffer,
    positions: wgpu::Buffer,
    rays: wgpu::Buffer,
    results: wgpu::Buffer,
    staging: wgpu::Buffer,
}

/// Where the f32 coordinates are centred and how large they are.
struct Scales {
    centre: Vec3,
    /// Largest |coordinate| (relative to `centre`) the box margins were set for.
    margin_scale: f64,
    /// Largest |coordinate| of this frame's positions (relative to `centre`).
    frame_scale: f64,
    /// Largest |coordinate| of the rest surface (relative to `centre`).
    rest_scale: f64,
}

/// The surface in f64 for the CPU decisions.
struct CpuSurface {
    triangles: Vec<[u32; 3]>,
    positions64: Vec<Vec3>,
    /// Triangles around each vertex (CSR): `fan[fan_start[v]..fan_start[v + 1]]`.
    fan_start: Vec<u32>,
    fan: Vec<u32>,
}

/// The lines decided on the CPU (flagged ones) and the tree they are cast on.
struct ExactLines {
    /// CPU tree for flagged lines, refit only in frames that have one.
    exact: BvhCaster,
    exact_stale: bool,
    /// The last cast had flagged lines: refit `exact` while the GPU works.
    expect_flagged: bool,
    flagged: Vec<usize>,
    flagged_lines: Vec<PairLine>,
    flagged_hits: Vec<PairHits>,
}

/// Uploads and readbacks reused from frame to frame.
struct Scratch {
    uploaded: Vec<[f32; 4]>,
    fresh: Vec<[f32; 4]>,
    gpu_rays: Vec<GpuRay>,
    /// Runs of changed vertices of this frame's upload.
    runs: Vec<(usize, usize)>,
    words: Vec<u32>,
}

fn to_f32(p: &Vec3, centre: &Vec3) -> [f32; 4] {
    let r = p - centre;
    [r.x as f32, r.y as f32, r.z as f32, 0.0]
}

fn gpu_err(what: &str, e: impl std::fmt::Display) -> CollisionError {
    CollisionError::Gpu(format!("{what}: {e}"))
}

fn max_abs(p: &Vec3, centre: &Vec3) -> f64 {
    (p - centre).amax()
}

fn storage(device: &wgpu::Device, label: &str, bytes: &[u8], extra: wgpu::BufferUsages) -> wgpu::Buffer {
    use wgpu::util::DeviceExt;
    // A zero-sized binding is invalid: keep at least 16 bytes.
    let mut data = bytes.to_vec();
    data.resize(data.len().max(16), 0);
    device.create_buffer_init(&wgpu::util::BufferInitDescriptor { label: Some(label), contents: &data, usage: wgpu::BufferUsages::STORAGE | extra })
}

/// A device of the adapter `WGPU_BACKEND` and `VK_DRIVER_FILES` choose, its limits, and a slot its errors and its
/// loss are reported into.
struct Opened {
    device: wgpu::Device,
    queue: wgpu::Queue,
    limits: wgpu::Limits,
    timestamp_query: bool,
    adapter_name: String,
    fault: Arc<Mutex<Option<String>>>,
}

fn open_device() -> Result<Opened, CollisionError> {
    let instance = wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
    let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
        power_preference: wgpu::PowerPreference::HighPerformance,
        ..Default::default()
    }))
    .map_err(|e| gpu_err("no adapter", e))?;
    let limits = adapter.limits();
    let timestamp_query = adapter.features().contains(wgpu::Features::TIMESTAMP_QUERY);
    let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
        label: Some("collision device"),
        required_limits: limits.clone(),
        required_features: if timestamp_query { wgpu::Features::TIMESTAMP_QUERY } else { wgpu::Features::empty() },
        ..Default::default()
    }))
    .map_err(|e| gpu_err("no device", e))?;
    let adapter_name = adapter.get_info().name;
    let fault = Arc::new(Mutex::new(None::<String>));
    {
        let sink = fault.clone();
        device.on_uncaptured_error(Arc::new(move |e: wgpu::Error| {
            if let Ok(mut f) = sink.lock() {
                f.get_or_insert_with(|| format!("device error: {e}"));
            }
        }));
        let sink = fault.clone();
        device.set_device_lost_callback(move |reason, message| {
            if let Ok(mut f) = sink.lock() {
                f.get_or_insert_with(|| format!("device lost ({reason:?}): {message}"));
            }
        });
    }

    Ok(Opened { device, queue, limits, timestamp_query, adapter_name, fault })
}

/// The traversal's parameters, its lines and results for up to `ray_capacity` lines, and the readback buffer.
fn line_buffers(device: &wgpu::Device, ray_capacity: usize) -> (wgpu::Buffer, wgpu::Buffer, wgpu::Buffer, wgpu::Buffer) {
    let copy_dst = wgpu::BufferUsages::COPY_DST;
    let params = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("collision params"),
        size: std::mem::size_of::<GpuParams>() as u64,
        usage: wgpu::BufferUsages::UNIFORM | copy_dst,
        mapped_at_creation: false,
    });
    let rays = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("collision rays"),
        size: (ray_capacity * std::mem::size_of::<GpuRay>()) as u64,
        usage: wgpu::BufferUsages::STORAGE | copy_dst,
        mapped_at_creation: false,
    });
    let results_size = (ray_capacity * OUT_STRIDE * 4) as u64;
    let results = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("collision results"),
        size: results_size,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    });
    // One readback a frame: the timestamps (32 bytes) first, then the results.
    let staging = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("collision staging"),
        size: STAMP_BYTES + results_size,
        usage: wgpu::BufferUsages::MAP_READ | copy_dst,
        mapped_at_creation: false,
    });
    (params, rays, results, staging)
}

/// The refit and traversal kernels over the tree of `layout` at `uploaded` positions, and the buffers of up to
/// `ray_capacity` lines a frame.
fn kernels(device: &wgpu::Device, limits: &wgpu::Limits, layout: &TreeLayout, uploaded: &[[f32; 4]], ray_capacity: usize) -> (Kernels, FrameBuffers) {
    let refit_shader = device.create_shader_module(wgpu::include_wgsl!("../../../shaders/collision_refit.wgsl"));
    let traverse_shader = device.create_shader_module(wgpu::include_wgsl!("../../../shaders/collision.wgsl"));
    let copy_dst = wgpu::BufferUsages::COPY_DST;
    let positions_buf = storage(device, "collision positions", bytemuck::cast_slice(uploaded), copy_dst);
    let topo = storage(device, "collision tree", bytemuck::cast_slice(&layout.topo), wgpu::BufferUsages::empty());
    let leaf_vertices = storage(device, "collision leaf vertices", bytemuck::cast_slice(&layout.leaf_vertices), wgpu::BufferUsages::empty());
    let leaf_tris = storage(device, "collision leaf triangles", bytemuck::cast_slice(&layout.leaf_triangles), wgpu::BufferUsages::empty());
    let level_nodes: Vec<u32> = layout.levels.iter().flatten().copied().collect();
    let level_nodes = storage(device, "collision level nodes", bytemuck::cast_slice(&level_nodes), wgpu::BufferUsages::empty());
    let boxes = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("collision boxes"),
        size: (layout.topo.len().max(1) * 32) as u64,
        usage: wgpu::BufferUsages::STORAGE,
        mapped_at_creation: false,
    });
    let mut levels = Vec::with_capacity(layout.levels.len());
    let mut start = 0u32;
    for l in &layout.levels {
        levels.push((start, l.len() as u32));
        start += l.len() as u32;
    }
    let level_stride = (limits.min_uniform_buffer_offset_alignment as u64).max(std::mem::size_of::<GpuLevel>() as u64);
    let levels_buf = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("collision levels"),
        size: level_stride * levels.len().max(1) as u64,
        usage: wgpu::BufferUsages::UNIFORM | copy_dst,
        mapped_at_creation: false,
    });
    let (params, rays, results, staging) = line_buffers(device, ray_capacity);
    let refit_pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some("collision refit"),
        layout: None,
        module: &refit_shader,
        entry_point: Some("refit"),
        compilation_options: Default::default(),
        cache: None,
    });
    let traverse_pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some("collision traversal"),
        layout: None,
        module: &traverse_shader,
        entry_point: Some("main"),
        compilation_options: Default::default(),
        cache: None,
    });
    let refit_layout = refit_pipeline.get_bind_group_layout(0);
    let refit_groups = (0..levels.len())
        .map(|k| {
            device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("collision refit level"),
                layout: &refit_layout,
                entries: &[
                    wgpu::BindGroupEntry {
                        binding: 0,
                        resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                            buffer: &levels_buf,
                            offset: k as u64 * level_stride,
                            size: wgpu::BufferSize::new(std::mem::size_of::<GpuLevel>() as u64),
                        }),
                    },
                    wgpu::BindGroupEntry { binding: 1, resource: positions_buf.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 2, resource: topo.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 3, resource: leaf_vertices.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 4, resource: level_nodes.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 5, resource: boxes.as_entire_binding() },
                ],
            })
        })
        .collect();
    let traverse_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("collision traversal"),
        layout: &traverse_pipeline.get_bind_group_layout(0),
        entries: &[
            wgpu::BindGroupEntry { binding: 0, resource: params.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 1, resource: positions_buf.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 2, resource: topo.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 3, resource: boxes.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 4, resource: leaf_tris.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 5, resource: rays.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 6, resource: results.as_entire_binding() },
        ],
    });
    let kernels = Kernels { refit_pipeline, traverse_pipeline, refit_groups, traverse_group, levels_buf, levels, level_stride };
    (kernels, FrameBuffers { params, positions: positions_buf, rays, results, staging })
}

impl GpuCaster {
    /// Creates device, pipelines and buffers for `triangles` at `positions` and up to
    /// `ray_capacity` lines a frame. Errors when no adapter or device is available,
    /// or when the tree or a buffer does not fit the shader or the adapter.
    pub fn new(triangles: &[[u32; 3]], positions: &[Vec3], ray_capacity: usize) -> Result<Self, CollisionError> {
        let exact = BvhCaster::new(triangles, positions);
        let layout = exact.layout();
        if layout.depth + 2 > SHADER_STACK {
            return Err(CollisionError::Gpu(format!("the tree is {} levels deep; the shader's stack holds {}", layout.depth, SHADER_STACK - 2)));
        }
        let Opened { device, queue, limits, timestamp_query, adapter_name, fault } = open_device()?;
        let (mut lo, mut hi) = (Vec3::repeat(f64::INFINITY), Vec3::repeat(f64::NEG_INFINITY));
        for p in positions {
            lo = lo.inf(p);
            hi = hi.sup(p);
        }
        let centre = if positions.is_empty() { Vec3::zeros() } else { (lo + hi) * 0.5 };
        let rest_scale = positions.iter().map(|p| max_abs(p, &centre)).fold(0.0, f64::max).max(f64::MIN_POSITIVE);
        let uploaded: Vec<[f32; 4]> = positions.iter().map(|p| to_f32(p, &centre)).collect();
        let ray_capacity = ray_capacity.max(1);
        let max_binding = limits.max_storage_buffer_binding_size as u64;
        let biggest = [uploaded.len() * 16, layout.leaf_triangles.len() * 16, layout.topo.len() * 32, ray_capacity * OUT_STRIDE * 4, ray_capacity * 32]
            .into_iter()
            .max()
            .unwrap_or(0) as u64;
        if biggest > max_binding {
            return Err(CollisionError::Gpu(format!("a buffer of {biggest} bytes exceeds the adapter's binding limit {max_binding}")));
        }
        let (kernels, buffers) = kernels(&device, &limits, &layout, &uploaded, ray_capacity);
        let timestamps = timestamp_query.then(|| Timestamps {
            set: device.create_query_set(&wgpu::QuerySetDescriptor { label: Some("collision timestamps"), ty: wgpu::QueryType::Timestamp, count: 4 }),
            resolve: device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("collision timestamp resolve"),
                size: 32,
                usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            }),
            period_ns: queue.get_timestamp_period() as f64,
        });

        // Triangles around each vertex, for the f64 decision's neighbourhood.
        let (fan_start, fan) = crate::mesh::triangles_around_vertices(positions.len(), triangles);
        let mut caster = Self {
            device,
            queue,
            kernels,
            buffers,
            timestamps,
            fault,
            scale: Scales { centre, margin_scale: 0.0, frame_scale: rest_scale, rest_scale },
            ray_capacity,
            scratch: Scratch {
                fresh: uploaded.clone(),
                uploaded,
                gpu_rays: Vec::with_capacity(ray_capacity),
                runs: Vec::new(),
                words: Vec::with_capacity(ray_capacity * OUT_STRIDE),
            },
            surface: CpuSurface { triangles: triangles.to_vec(), positions64: positions.to_vec(), fan_start, fan },
            cpu: ExactLines { exact, exact_stale: false, expect_flagged: false, flagged: Vec::new(), flagged_lines: Vec::new(), flagged_hits: Vec::new() },
            adapter_name,
            last_upload: UploadStats::default(),
            last_timings: GpuTimings::default(),
            fail_next: false,
        };
        caster.write_margins(rest_scale);
        caster.check_fault()?;
        Ok(caster)
    }

    /// The window `w` for coordinates up to `scale`, metres.
    fn window(scale: f64) -> f64 {
        WINDOW_ULPS * f32::EPSILON as f64 * scale
    }

    /// Writes the leaf-box margin (`w/2` for coordinates up to `scale`, with headroom
    /// so that a slowly growing surface does not rewrite it every frame).
    fn write_margins(&mut self, scale: f64) {
        let scale = scale * 1.25;
        let margin = (0.5 * Self::window(scale)) as f32;
        let mut bytes = vec![0u8; self.kernels.level_stride as usize * self.kernels.levels.len()];
        for (k, &(start, count)) in self.kernels.levels.iter().enumerate() {
            let l = GpuLevel { start, count, margin, _pad: 0 };
            let at = k * self.kernels.level_stride as usize;
            bytes[at..at + std::mem::size_of::<GpuLevel>()].copy_from_slice(bytemuck::bytes_of(&l));
        }
        if !bytes.is_empty() {
            self.queue.write_buffer(&self.kernels.levels_buf, 0, &bytes);
        }
        self.scale.margin_scale = scale;
    }

    fn check_fault(&self) -> Result<(), CollisionError> {
        match self.fault.lock().map(|f| f.clone()) {
            Ok(Some(msg)) => Err(CollisionError::Gpu(msg)),
            Ok(None) => Ok(()),
            Err(_) => Err(CollisionError::Gpu("the device's error sink was poisoned".into())),
        }
    }

    /// The adapter's name (e.g. "llvmpipe" for Mesa lavapipe).
    pub fn adapter_name(&self) -> &str {
        &self.adapter_name
    }

    /// How the last [`RayCaster::update_surface`] uploaded positions.
    pub fn last_upload(&self) -> UploadStats {
        self.last_upload
    }

    /// Where the last cast spent its time.
    pub fn last_timings(&self) -> GpuTimings {
        self.last_timings
    }

    /// The last cast's flag word of every line (0: decided from its candidates; bits
    /// 1, 2, 4 as in `GpuTimings::flag_reasons`, 8: an origin too far for f32).
    pub fn last_flags(&self) -> impl Iterator<Item = u32> + '_ {
        self.scratch.words.chunks_exact(OUT_STRIDE).map(|w| w[12])
    }

    /// True when the adapter reports timestamp queries (the GPU breakdown).
    pub fn has_timestamps(&self) -> bool {
        self.timestamps.is_some()
    }

    /// The f64 answer of one unflagged line from its candidates.
    fn decide(&self, line: &PairLine, words: &[u32], seen: &mut Vec<u32>) -> PairHits {
        let mut acc = LineAccumulator::new(line.thickness);
        let Some(q) = LineQuery::new(line.origin, line.direction) else {
            return acc.finish();
        };
        seen.clear();
        for &t in &words[..12] {
            if t != NO_HIT && (t as usize) < self.surface.triangles.len() && !seen.contains(&t) {
                seen.push(t);
            }
        }
        let candidates = seen.len();
        let mut i = 0;
        while i < seen.len() {
            let t = seen[i];
            let tri = self.surface.triangles[t as usize];
            let [a, b, c] = tri.map(|v| &self.surface.positions64[v as usize]);
            match q.intersect(a, b, c) {
                Some(h) => acc.offer(TriangleHit { triangle: t, t: h.t, u: h.u, v: h.v }),
                None if i < candidates => {
                    // f32 hit, f64 miss: the line passes at an edge or a vertex, and the
                    // f64 test hits one of the triangles around it.
                    for v in tri {
                        for &u in &self.surface.fan[self.surface.fan_start[v as usize] as usize..self.surface.fan_start[v as usize + 1] as usize] {
                            if !seen.contains(&u) {
                                seen.push(u);
                            }
                        }
                    }
                }
                None => {}
            }
            i += 1;
        }
        acc.finish()
    }

    /// Records, submits and waits for one frame's GPU work; fills `self.scratch.words`.
    fn run_device(&mut self, lines: &[PairLine]) -> Result<(Option<f64>, Option<f64>), CollisionError> {
        let scale = lines.iter().map(|l| max_abs(&l.origin, &self.scale.centre)).fold(self.scale.frame_scale, f64::max);
        let params = GpuParams { line_count: lines.len() as u32, _pad: [0; 3], window: Self::window(scale) as f32, coord_scale: scale as f32, _pad2: [0.0; 2] };
        self.queue.write_buffer(&self.buffers.params, 0, bytemuck::bytes_of(&params));
        self.queue.write_buffer(&self.buffers.rays, 0, bytemuck::cast_slice(&self.scratch.gpu_rays));
        let bytes = (lines.len() * OUT_STRIDE * 4) as u64;
        let mut encoder = self.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("collision encoder") });
        let writes = |begin: u32| {
            self.timestamps.as_ref().map(|ts| wgpu::ComputePassTimestampWrites {
                query_set: &ts.set,
                beginning_of_pass_write_index: Some(begin),
                end_of_pass_write_index: Some(begin + 1),
            })
        };
        {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some("collision refit"), timestamp_writes: writes(0) });
            pass.set_pipeline(&self.kernels.refit_pipeline);
            for (group, &(_, count)) in self.kernels.refit_groups.iter().zip(&self.kernels.levels) {
                pass.set_bind_group(0, group, &[]);
                pass.dispatch_workgroups(count.div_ceil(WORKGROUP), 1, 1);
            }
        }
        {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some("collision traversal"), timestamp_writes: writes(2) });
            pass.set_pipeline(&self.kernels.traverse_pipeline);
            pass.set_bind_group(0, &self.kernels.traverse_group, &[]);
            pass.dispatch_workgroups((lines.len() as u32).div_ceil(WORKGROUP), 1, 1);
        }
        encoder.copy_buffer_to_buffer(&self.buffers.results, 0, &self.buffers.staging, STAMP_BYTES, bytes);
        if let Some(ts) = &self.timestamps {
            encoder.resolve_query_set(&ts.set, 0..4, &ts.resolve, 0);
            encoder.copy_buffer_to_buffer(&ts.resolve, 0, &self.buffers.staging, 0, STAMP_BYTES);
        }
        self.queue.submit(Some(encoder.finish()));
        let (tx, rx) = std::sync::mpsc::channel();
        let mapped = STAMP_BYTES + bytes;
        self.buffers.staging.map_async(wgpu::MapMode::Read, 0..mapped, move |r| {
            let _ = tx.send(r);
        });
        // The GPU works now: refit the CPU tree for the flagged lines meanwhile when
        // the last frame had some (the refit changes no answer, only when it is paid).
        if self.cpu.expect_flagged && self.cpu.exact_stale {
            self.cpu.exact.update_surface(&self.surface.positions64)?;
            self.cpu.exact_stale = false;
        }
        self.device.poll(wgpu::PollType::wait_indefinitely()).map_err(|e| gpu_err("poll", e))?;
        rx.recv().map_err(|e| gpu_err("readback", e))?.map_err(|e| gpu_err("map", e))?;
        self.check_fault()?;
        let mut gpu_times = (None, None);
        {
            let view = self.buffers.staging.get_mapped_range(0..mapped).map_err(|e| gpu_err("mapped range", e))?;
            let (stamps, words) = view.split_at(STAMP_BYTES as usize);
            self.scratch.words.clear();
            self.scratch.words.extend_from_slice(bytemuck::cast_slice(words));
            if let Some(ts) = &self.timestamps {
                let mut q = [0u64; 4];
                for (q, c) in q.iter_mut().zip(stamps.chunks_exact(8)) {
                    *q = <[u8; 8]>::try_from(c).map_or(0, u64::from_le_bytes);
                }
                let span = |a: u64, b: u64| (b >= a && a > 0).then(|| (b - a) as f64 * ts.period_ns * 1e-9);
                gpu_times = (span(q[0], q[1]), span(q[2], q[3]));
            }
        }
        self.buffers.staging.unmap();
        Ok(gpu_times)
    }
}

impl RayCaster for GpuCaster {
    fn kind(&self) -> BackendKind {
        BackendKind::Gpu
    }

    fn update_surface(&mut self, positions: &[Vec3]) -> Result<(), CollisionError> {
        if positions.len() != self.scratch.uploaded.len() {
            return Err(CollisionError::VertexCount { expected: self.scratch.uploaded.len(), got: positions.len() });
        }
        let t0 = Instant::now();
        self.surface.positions64.copy_from_slice(positions);
        self.cpu.exact_stale = true;
        // One pass: the f32 value, the frame's scale and the runs of changed vertices
        // (gaps of up to RUN_GAP unchanged ones bridged).
        let mut changed = 0;
        let mut scale = self.scale.rest_scale;
        self.scratch.runs.clear();
        for (i, ((f, p), u)) in self.scratch.fresh.iter_mut().zip(positions).zip(&self.scratch.uploaded).enumerate() {
            *f = to_f32(p, &self.scale.centre);
            scale = scale.max(max_abs(p, &self.scale.centre));
            if *f != *u {
                changed += 1;
                match self.scratch.runs.last_mut() {
                    Some(r) if i - r.1 <= RUN_GAP => r.1 = i + 1,
                    _ => self.scratch.runs.push((i, i + 1)),
                }
            }
        }
        self.scale.frame_scale = scale;
        if scale > self.scale.margin_scale {
            self.write_margins(scale);
        }
        let mut stats = UploadStats { changed_vertices: changed, ..Default::default() };
        let n = self.scratch.fresh.len();
        if changed * 2 > n {
            self.queue.write_buffer(&self.buffers.positions, 0, bytemuck::cast_slice(&self.scratch.fresh));
            stats.whole_buffer = true;
            stats.writes = 1;
            stats.written_vertices = n;
        } else if self.scratch.runs.len() > MAX_WRITES {
            // Each write_buffer is a staging allocation and a copy command: past
            // MAX_WRITES runs, one span from the first changed vertex to the last.
            let (start, end) = (self.scratch.runs[0].0, self.scratch.runs[self.scratch.runs.len() - 1].1);
            self.queue.write_buffer(&self.buffers.positions, (start * 16) as u64, bytemuck::cast_slice(&self.scratch.fresh[start..end]));
            stats.writes = 1;
            stats.written_vertices = end - start;
        } else {
            for &(start, end) in &self.scratch.runs {
                self.queue.write_buffer(&self.buffers.positions, (start * 16) as u64, bytemuck::cast_slice(&self.scratch.fresh[start..end]));
                stats.writes += 1;
                stats.written_vertices += end - start;
            }
        }
        std::mem::swap(&mut self.scratch.uploaded, &mut self.scratch.fresh);
        self.last_upload = stats;
        self.last_timings.upload = t0.elapsed().as_secs_f64();
        Ok(())
    }

    fn gpu_timings(&self) -> Option<GpuTimings> {
        Some(self.last_timings)
    }

    fn device_name(&self) -> Option<String> {
        Some(self.adapter_name.clone())
    }

    /// The next `cast` fails as a lost device would, and the device is destroyed,
    /// so every later call fails too.
    fn simulate_device_loss(&mut self) -> bool {
        self.fail_next = true;
        self.device.destroy();
        true
    }

    fn cast(&mut self, lines: &[PairLine], out: &mut Vec<PairHits>) -> Result<(), CollisionError> {
        out.clear();
        let upload = std::mem::take(&mut self.last_timings.upload);
        self.last_timings = GpuTimings { upload, lines: lines.len(), ..Default::default() };
        if lines.is_empty() {
            return Ok(());
        }
        if self.fail_next {
            self.fail_next = false;
            return Err(CollisionError::Gpu("device lost (simulated)".into()));
        }
        if lines.len() > self.ray_capacity {
            return Err(CollisionError::Gpu(format!("{} lines exceed the capacity {}", lines.len(), self.ray_capacity)));
        }
        let t0 = Instant::now();
        let far = FAR_ORIGIN * self.scale.rest_scale;
        self.scratch.gpu_rays.clear();
        self.scratch.gpu_rays.extend(lines.iter().map(|r| GpuRay {
            origin: {
                let mut o = to_f32(&r.origin, &self.scale.centre);
                o[3] = r.thickness as f32;
                o
            },
            direction: [r.direction.x as f32, r.direction.y as f32, r.direction.z as f32, (super::CONTACT_TOLERANCE_RELATIVE * r.thickness) as f32],
        }));
        let (refit_gpu, traverse_gpu) = self.run_device(lines)?;
        let t1 = Instant::now();

        // One pass over the flag words: absurdly far origins join the flagged lines
        // (FAR_FLAG), which the CPU tree casts below; the reasons are counted.
        self.cpu.flagged.clear();
        self.cpu.flagged_lines.clear();
        let mut reasons = [0; 3];
        for (k, (l, w)) in lines.iter().zip(self.scratch.words.chunks_exact_mut(OUT_STRIDE)).enumerate() {
            if max_abs(&l.origin, &self.scale.centre) > far {
                w[12] |= FAR_FLAG;
            }
            for (bit, r) in reasons.iter_mut().enumerate() {
                *r += (w[12] >> bit & 1) as usize;
            }
            if w[12] != 0 {
                self.cpu.flagged.push(k);
                self.cpu.flagged_lines.push(*l);
            }
        }
        // Decide every unflagged line in f64 from its candidates (lines are independent
        // and land in fixed slots, so the split over threads changes no answer).
        out.resize(lines.len(), PairHits::default());
        let this = &*self;
        let decide_chunk = |o: &mut [PairHits], l: &[PairLine], w: &[u32]| {
            SEEN.with_borrow_mut(|seen| {
                for ((o, l), w) in o.iter_mut().zip(l).zip(w.chunks_exact(OUT_STRIDE)) {
                    if w[12] == 0 {
                        *o = this.decide(l, w, seen);
                    }
                }
            })
        };
        if lines.len() >= 2 * LINES_PER_TASK && rayon::current_num_threads() > 1 {
            use rayon::prelude::*;
            out.par_chunks_mut(LINES_PER_TASK)
                .zip(lines.par_chunks(LINES_PER_TASK))
                .zip(self.scratch.words.par_chunks(LINES_PER_TASK * OUT_STRIDE))
                .for_each(|((o, l), w)| decide_chunk(o, l, w));
        } else {
            decide_chunk(out, lines, &self.scratch.words);
        }
        if !self.cpu.flagged.is_empty() {
            if self.cpu.exact_stale {
                self.cpu.exact.update_surface(&self.surface.positions64)?;
                self.cpu.exact_stale = false;
            }
            self.cpu.exact.cast(&self.cpu.flagged_lines, &mut self.cpu.flagged_hits)?;
            for (&k, h) in self.cpu.flagged.iter().zip(&self.cpu.flagged_hits) {
                out[k] = *h;
            }
        }
        self.last_timings.wait = (t1 - t0).as_secs_f64();
        self.last_timings.decide = t1.elapsed().as_secs_f64();
        self.last_timings.refit_gpu = refit_gpu;
        self.last_timings.traverse_gpu = traverse_gpu;
        self.last_timings.flagged_lines = self.cpu.flagged.len();
        self.cpu.expect_flagged = !self.cpu.flagged.is_empty();
        self.last_timings.flag_reasons = reasons;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pod_twins_match_the_wgsl_layout() {
        assert_eq!(std::mem::size_of::<GpuParams>(), 32, "Params is 4 x u32 then 4 x f32 in the shader");
        assert_eq!(std::mem::size_of::<GpuRay>(), 32, "Ray is two vec4<f32> in the shader");
        assert_eq!(std::mem::size_of::<GpuLevel>(), 16, "Level is (u32, u32, f32, u32) in the refit shader");
    }
}

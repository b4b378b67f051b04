//! The GPU tracer (feature `gpu`): the same estimators as the CPU tracer as one wgpu
//! compute shader (the files of `shader/`, joined by `shader.rs`), on any Vulkan, Metal
//! or DX12 adapter — in CI, Mesa's software rasteriser lavapipe.
//!
//! Design: a megakernel — one invocation traces one pixel's whole path per pass, in
//! 8 × 8 workgroups. A wavefront design (a kernel per bounce, queues of rays between)
//! keeps SIMD lanes busier on a GPU when paths diverge; the megakernel has one
//! dispatch per pass, no ray queues in memory, and the integrator reads like the CPU's
//! line for line, which is what the agreement tests need first.
//!
//! Scene upload (once): obvhs's BVH2 flattened by [`guiding_obvhs::flat_bvh2`] (32-byte
//! nodes, triangles in leaf order), per-triangle geometric normal and material, the
//! materials, the area lights with their power CDF (guiding-core's
//! [`cdf`](guiding_core::cdf) layout, unchanged). Each pass writes its image; the host
//! adds it into the f64 film and takes the pass mean, as the CPU renderer does.
//!
//! Guiding: a [`HemisphereGrid`](guiding_core::HemisphereGrid)'s flat arrays are uploaded
//! as they are (positions and normals as f32 triples, Q as f32 bits, visits, CDFs,
//! Lambertian sums, the hash grid's bucket table); the shader locates the nearest probe
//! with a similar normal, samples ∝ Q by CDF inversion, evaluates the mixture pdf for
//! MIS, and learns by Eq. (1)/(2) with compare-exchange float updates on `atomic<u32>`. A
//! second kernel rebuilds the CDFs of the probes that learned between passes. After the
//! render Q and the visit counts are read back into the same grid ([`store_learned`]),
//! which the CPU tracer can then use or save.
//!
//! An [`IrradianceVolume`](guiding_core::IrradianceVolume) follows the same pattern: its
//! octree nodes, Q, visits, CDFs and spherical-harmonic coefficients are uploaded as they
//! are (with room for every leaf its budget allows); the shader walks the tree to the
//! leaf, samples the sphere folded onto the normal's hemisphere, takes the Lambertian
//! integral from the harmonics, and learns by Eq. (1); the rebuild kernel projects each
//! changed leaf again. Splitting busy leaves stays on the host: after each pass the leaf
//! visit counts come back (a few KiB), and only when guiding-core says a split is due
//! ([`IrradianceVolume::splits_pending`](guiding_core::IrradianceVolume::splits_pending))
//! do the tables come home, split, and go back.
//!
//! A [`GaussianMixture`](guiding_core::GaussianMixture) runs its E-step on the GPU: its
//! lobe table (mean, κ, C(κ), weight per lobe; guiding-core's
//! [`GaussianMixture::lobe_table`](guiding_core::GaussianMixture::lobe_table)) and its
//! batch words are uploaded; the shader finds the region by cell and normal side, samples
//! and evaluates the mixture exactly, and adds each sample's responsibilities into the
//! batch sums by compare-exchange. The M-step (guiding-core's own, with its learning
//! rate) runs on the host after each pass on the batch read back (a few KiB), and the
//! refitted lobes go up again.
//!
//! A [`SpatialDirectionalTree`](guiding_core::SpatialDirectionalTree) goes up as its
//! [`FlatTree`](guiding_core::FlatTree) (spatial nodes and leaves, the quadtrees'
//! children and cell probabilities, those under the cosine product), with room for all
//! its budget allows. The shader descends the spatial tree to the leaf and each leaf's
//! quadtree to sample and evaluate, as guiding-core does, and appends each learned
//! vertex as a record (leaf and half, normal, direction, target, pdf; 36 bytes) to a
//! buffer with room for 16 per pixel, at most 2²⁰ a pass. After every learning pass the
//! host reads the records, splats them into its copy of the tree, refits it (the CPU's
//! online schedule) and uploads it again.
//!
//! What runs on the GPU: diffuse, conductor (GGX, optional complex-IOR Fresnel),
//! dielectric and thin dielectric materials; area lights; a constant environment;
//! geometric normals; all four directional guides — the hemisphere grid in its
//! cylindrical layout and the irradiance volume with the simple, region or exponential
//! learning rates, the mixture and the tree with any. Scenes or settings needing more
//! (textures, masks, plastic, an image environment) are refused with a message naming
//! what is missing.

mod backend;
mod context;
mod guide_buffers;
mod params;
mod readback;
mod scene_buffers;
mod shader;
mod tree_upload;

use std::time::Instant;

use glam::Vec3;
use wgpu::util::DeviceExt;

pub use backend::GpuBackend;
pub use context::GpuContext;
pub use guide_buffers::{store_learned, GpuGuide};
use guide_buffers::{GuideBuffers, HostGuide};
use params::{method_code, Params};
use scene_buffers::SceneBuffers;

use crate::environment::Sky;
use crate::film::Film;
use crate::integrator::{IntegratorSettings, PathCounters};
use crate::output::Image;
use crate::render::{end_of_pass, pass_seed, PassFate, Progress, RenderSettings, RenderStatistics};
use crate::scene::Scene;

/// The compute pipeline of the shader's entry point `name` (layout from the shader).
fn entry_point(device: &wgpu::Device, module: &wgpu::ShaderModule, name: &str) -> wgpu::ComputePipeline {
    device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some(name),
        layout: None,
        module,
        entry_point: Some(name),
        compilation_options: Default::default(),
        cache: None,
    })
}

/// A scene uploaded to a GPU, ready to render passes.
pub struct GpuTracer {
    context: GpuContext,
    /// The shader ([`shader::source`]), compiled once for every entry point.
    module: wgpu::ShaderModule,
    pipeline: wgpu::ComputePipeline,
    bind_group: wgpu::BindGroup,
    rebuild: wgpu::ComputePipeline,
    rebuild_group: wgpu::BindGroup,
    guide: GuideBuffers,
    /// The host's copy of an uploaded guide that the host refits between passes.
    host: Option<HostGuide>,
    /// What the host reads after every learning pass ([`HostGuide::pass_readback`]).
    host_readback: wgpu::Buffer,
    params: Params,
    params_buffer: wgpu::Buffer,
    image: wgpu::Buffer,
    image_readback: wgpu::Buffer,
    counters: wgpu::Buffer,
    counters_readback: wgpu::Buffer,
    width: u32,
    height: u32,
}

/// What the GPU tracer cannot render in `scene`, if anything.
pub fn unsupported(scene: &Scene) -> Option<String> {
    if let Some(environment) = &scene.environment {
        if matches!(environment.sky, Sky::Image(_)) {
            return Some("an image environment".into());
        }
        if environment.sun.is_some() {
            return Some("a sun".into());
        }
    }
    if !scene.textures.is_empty() {
        return Some("textures".into());
    }
    scene_buffers::unsupported_material(scene)
}

impl GpuTracer {
    /// Uploads `scene` for `settings.method`, and `guide` for the guided methods. Errors
    /// name what is missing: an adapter, or a feature the GPU tracer lacks.
    pub fn new(
        context: GpuContext,
        scene: &Scene,
        settings: &IntegratorSettings,
        guide: Option<GpuGuide<'_>>,
    ) -> Result<Self, String> {
        if let Some(what) = unsupported(scene) {
            return Err(format!("the GPU tracer does not support {what} yet (render with --device cpu)"));
        }
        let guide = guide.filter(|_| settings.method.uses_guide());
        if settings.method.uses_guide() && guide.is_none() {
            return Err("the GPU tracer needs the directional guide of the guided methods".into());
        }
        if let Some(what) = guide.and_then(guide_buffers::unsupported) {
            return Err(format!("the GPU guide does not support {what} yet"));
        }
        let device = &context.device;
        let buffers = SceneBuffers::new(scene)?;
        let (width, height) = (scene.camera.width, scene.camera.height);
        let (eye, forward, right, up, tan_half_fov_y) = scene.camera.basis();
        let (low, high) = scene.bounds();
        let environment = match &scene.environment {
            Some(environment) => match environment.sky {
                Sky::Constant(radiance) => radiance,
                Sky::Image(_) => Vec3::ZERO,
            },
            None => Vec3::ZERO,
        };
        // Probability that next-event estimation picks the environment (integrator.rs).
        let environment_choice = match (scene.environment.is_some(), scene.lights.is_empty()) {
            (true, true) => 1.0,
            (true, false) => 0.5,
            (false, _) => 0.0,
        };
        let params = Params {
            width,
            height,
            max_depth: settings.max_depth,
            rr_depth: settings.rr_depth,
            method: method_code(settings.method),
            light_count: scene.lights.len() as u32,
            eye: eye.to_array(),
            ray_epsilon: 1e-5 * (high - low).length().max(f32::MIN_POSITIVE),
            forward: forward.to_array(),
            tan_half_fov_y,
            right: right.to_array(),
            guide_probability: settings.guide_probability,
            up: up.to_array(),
            environment_radiance: environment.to_array(),
            environment_choice,
            guide_present: guide.is_some() as u32,
            guide_learns: (guide.is_some() && settings.learn) as u32,
            ..Default::default()
        };
        let mut params = params;
        if let Some(guide) = guide {
            guide.write_params(&mut params);
        }
        let params_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("params"),
            contents: bytemuck::bytes_of(&params),
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        });
        let pixels = width as u64 * height as u64;
        let image_bytes = pixels * 16;
        let image = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("pass image"),
            size: image_bytes,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let image_readback = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("pass image readback"),
            size: image_bytes,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let counters = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("counters"),
            size: 16,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let counters_readback = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("counters readback"),
            size: 16,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("tracer"),
            source: wgpu::ShaderSource::Wgsl(shader::source().into()),
        });
        let pipeline = entry_point(device, &module, "trace");
        let rebuild = entry_point(device, &module, "rebuild");
        let storage = buffers.uploaded(device);
        let guide_buffers = GuideBuffers::new(device, guide, &params)?;
        let g = &guide_buffers;
        let all = [
            &params_buffer,
            &storage.nodes,
            &storage.triangles,
            &storage.triangle_info,
            &storage.light_of_triangle,
            &storage.materials,
            &storage.lights,
            &storage.light_cdf,
            &image,
            &counters,
            &g.positions,
            &g.normals,
            &g.index_table,
            &g.q,
            &g.patch_visits,
            &g.region_visits,
            &g.cdf,
            &g.integral_terms,
            &g.patch_weights,
            &g.built_visits,
        ];
        let group = |pipeline: &wgpu::ComputePipeline, bindings: &[u32], label: &str| {
            let entries: Vec<wgpu::BindGroupEntry> = bindings
                .iter()
                .map(|&b| wgpu::BindGroupEntry { binding: b, resource: all[b as usize].as_entire_binding() })
                .collect();
            device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some(label),
                layout: &pipeline.get_bind_group_layout(0),
                entries: &entries,
            })
        };
        // Automatic layouts hold only the bindings an entry point uses: the rebuild
        // kernel alone keeps the visit counts of the last build.
        let bind_group = group(&pipeline, &(0..19).collect::<Vec<u32>>(), "trace");
        let rebuild_group = group(&rebuild, &[0, 13, 15, 16, 17, 18, 19], "rebuild");
        context.check_errors()?;
        let host = guide.and_then(GpuGuide::host_copy);
        let host_readback = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("host readback"),
            size: host.as_ref().map_or(guide_buffers.region_visits.size(), |h| h.pass_readback(&guide_buffers).size()),
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        Ok(Self {
            context,
            module,
            pipeline,
            bind_group,
            rebuild,
            rebuild_group,
            guide: guide_buffers,
            host,
            host_readback,
            params,
            params_buffer,
            image,
            image_readback,
            counters,
            counters_readback,
            width,
            height,
        })
    }

    /// Traces one pass; returns its image (radiance per pixel, top row first) and counters.
    pub fn trace_pass(&mut self, pass_index: u32, seed: u64) -> Result<(Vec<[f32; 4]>, PathCounters), String> {
        let (device, queue) = (&self.context.device, &self.context.queue);
        self.params.pass_index = pass_index;
        self.params.seed = (seed ^ (seed >> 32)) as u32;
        queue.write_buffer(&self.params_buffer, 0, bytemuck::bytes_of(&self.params));
        queue.write_buffer(&self.counters, 0, &[0u8; 16]);
        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("pass") });
        {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor::default());
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, &self.bind_group, &[]);
            pass.dispatch_workgroups(self.width.div_ceil(8), self.height.div_ceil(8), 1);
            if self.params.guide_learns != 0 && self.host.as_ref().is_none_or(HostGuide::rebuilt_on_gpu) {
                // Between passes: the CDFs of the probes or leaves that learned.
                pass.set_pipeline(&self.rebuild);
                pass.set_bind_group(0, &self.rebuild_group, &[]);
                pass.dispatch_workgroups(self.params.guide_regions.div_ceil(64), 1, 1);
            }
        }
        encoder.copy_buffer_to_buffer(&self.image, 0, &self.image_readback, 0, self.image.size());
        encoder.copy_buffer_to_buffer(&self.counters, 0, &self.counters_readback, 0, 16);
        let learning = self.params.guide_learns != 0;
        if let Some(host) = self.host.as_ref().filter(|_| learning) {
            let source = host.pass_readback(&self.guide);
            encoder.copy_buffer_to_buffer(source, 0, &self.host_readback, 0, self.host_readback.size());
        }
        queue.submit([encoder.finish()]);
        let image: Vec<[f32; 4]> = self.context.read(&self.image_readback)?;
        let counts: Vec<u32> = self.context.read(&self.counters_readback)?;
        if let Some(host) = self.host.as_mut().filter(|_| learning) {
            let words: Vec<u32> = self.context.read(&self.host_readback)?;
            host.refit(&words, &self.context, &self.guide, &mut self.params)?;
        }
        let counters = PathCounters {
            paths: counts[0] as u64,
            nonzero_paths: counts[1] as u64,
            rays: counts[2] as u64,
            vertices: counts[3] as u64,
            ..Default::default()
        };
        Ok((image, counters))
    }

    /// Renders progressively like [`crate::render::render`]: one pass per sample per
    /// pixel until the budget, training passes (`settings.train_seconds`) discarded;
    /// `on_pass` sees the state after every pass.
    pub fn render(
        &mut self,
        settings: &RenderSettings,
        mut on_pass: impl FnMut(&Progress),
    ) -> Result<(Image, RenderStatistics), String> {
        let (width, height) = (self.width as usize, self.height as usize);
        let mut film = Film::new(width, height, settings.combine);
        let mut statistics = RenderStatistics::default();
        let start = Instant::now();
        // Passes traced so far, kept or not: each gets its own seed.
        let mut traced = 0u32;
        loop {
            let pass = traced;
            traced += 1;
            let (image, counters) = self.trace_pass(pass, pass_seed(settings.seed, pass))?;
            let mut sum = [0.0f64; 3];
            for (pixel, value) in film.pixels_mut().iter_mut().zip(&image) {
                // A NaN or infinite sample counts as lost, as on the CPU.
                let v = [value[0], value[1], value[2]].map(|c| if c.is_finite() { c } else { 0.0 });
                Film::add(pixel, Vec3::from_array(v));
                for c in 0..3 {
                    sum[c] += v[c] as f64;
                }
            }
            film.end_pass();
            statistics.add_pass(sum, width * height, counters);
            let learns = self.params.guide_learns != 0;
            let fate = if learns && start.elapsed().as_secs_f64() < settings.train_seconds {
                PassFate::Discard
            } else {
                PassFate::Keep
            };
            if let Some(HostGuide::Tree(tree)) = &self.host {
                statistics.lost_records = tree.lost_records;
            }
            if end_of_pass(&mut film, &mut statistics, settings, fate, start, &mut on_pass) {
                break;
            }
        }
        Ok((film.image(), statistics))
    }
}

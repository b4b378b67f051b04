//! What the GPU learned, read back into the core's structures, and guide samples drawn
//! on the GPU for the tests.

use glam::Vec3;
use guiding_core::{GaussianMixture, Guide, HemisphereGrid, IrradianceVolume};

use super::{entry_point, guide_buffers, store_learned, GpuTracer};
use crate::directional_guide::DirectionalGuide;

impl GpuTracer {
    /// Reads what `guide` (the guide this tracer was built with) learned on the GPU back
    /// into it.
    pub fn download(&self, guide: &mut DirectionalGuide) -> Result<(), String> {
        match guide {
            DirectionalGuide::Hemisphere(grid) => self.download_guide(grid),
            DirectionalGuide::Volume(volume) => self.download_volume(volume),
            DirectionalGuide::Mixture(mixture) => self.download_mixture(mixture),
            DirectionalGuide::Tree(_) => Err("the GPU tracer has no tree guide yet".into()),
        }
    }

    /// Replaces `mixture` by the uploaded one as it learned on the GPU (every pass's
    /// batch already absorbed on the host).
    pub fn download_mixture(&self, mixture: &mut GaussianMixture) -> Result<(), String> {
        let Some(learned) = self.mixture.as_ref() else {
            return Err("no mixture was uploaded".into());
        };
        mixture.clone_from(learned);
        Ok(())
    }

    /// Reads the learned Q and visit counts back into `volume` (replaced by the
    /// uploaded volume as it learned and split on the GPU) and rebuilds its sampling.
    pub fn download_volume(&self, volume: &mut IrradianceVolume) -> Result<(), String> {
        let Some(learned) = self.volume.as_ref() else {
            return Err("no irradiance volume was uploaded".into());
        };
        let mut learned = learned.clone();
        let leaves = learned.leaf_count();
        let entries = leaves * learned.patch_count();
        let q = self.read_back(&self.guide.q)?;
        let patch_visits = self.read_back(&self.guide.patch_visits)?;
        let leaf_visits = self.read_back(&self.guide.region_visits)?;
        guide_buffers::store_volume_tables(&learned, &q[..entries], &patch_visits[..entries], &leaf_visits[..leaves]);
        learned.rebuild_sampling();
        *volume = learned;
        Ok(())
    }

    /// Reads the learned Q and visit counts back into `grid` (the grid this tracer was
    /// built with) and rebuilds its sampling ([`store_learned`]).
    pub fn download_guide(&self, grid: &mut HemisphereGrid) -> Result<(), String> {
        if self.volume.is_some()
            || self.mixture.is_some()
            || self.params.guide_regions as usize != grid.probe_count()
            || self.params.guide_patches as usize != grid.patch_count()
        {
            return Err("the grid does not match the one uploaded".into());
        }
        let q = self.read_back(&self.guide.q)?;
        let patch_visits = self.read_back(&self.guide.patch_visits)?;
        let probe_visits = self.read_back(&self.guide.region_visits)?;
        store_learned(grid, &q, &patch_visits, &probe_visits);
        Ok(())
    }

    /// Draws `count` directions from region `region`'s distribution on the GPU (unit
    /// direction and the GPU's pdf per steradian each), for tests of the GPU sampler: a
    /// probe of the grid, or a leaf of the volume folded about `normal`.
    pub fn sample_guide(&mut self, region: u32, normal: Vec3, count: u32, seed: u32) -> Result<Vec<[f32; 4]>, String> {
        if region >= self.params.guide_regions {
            return Err(format!("region {region} of {}", self.params.guide_regions));
        }
        let device = &self.context.device;
        let samples = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("guide samples"),
            size: count.max(1) as u64 * 16,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let pipeline = entry_point(device, &self.module, "sample_guide");
        let entries = [
            wgpu::BindGroupEntry { binding: 0, resource: self.params_buffer.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 11, resource: self.guide.normals.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 16, resource: self.guide.cdf.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 20, resource: samples.as_entire_binding() },
        ];
        let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("sample_guide"),
            layout: &pipeline.get_bind_group_layout(0),
            entries: &entries,
        });
        self.params.pass_index = region;
        self.params.seed = seed;
        self.params.sample_normal = normal.to_array();
        self.context.queue.write_buffer(&self.params_buffer, 0, bytemuck::bytes_of(&self.params));
        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("sample") });
        {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor::default());
            pass.set_pipeline(&pipeline);
            pass.set_bind_group(0, &group, &[]);
            pass.dispatch_workgroups(count.div_ceil(64), 1, 1);
        }
        self.context.queue.submit([encoder.finish()]);
        let words = self.read_back(&samples)?;
        let sample = |c: &[u32]| [c[0], c[1], c[2], c[3]].map(f32::from_bits);
        Ok(words.chunks_exact(4).map(sample).take(count as usize).collect())
    }

    /// Copies a storage buffer to the host.
    pub(super) fn read_back(&self, buffer: &wgpu::Buffer) -> Result<Vec<u32>, String> {
        let device = &self.context.device;
        let staging = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("guide readback"),
            size: buffer.size(),
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("readback") });
        encoder.copy_buffer_to_buffer(buffer, 0, &staging, 0, buffer.size());
        self.context.queue.submit([encoder.finish()]);
        self.context.read(&staging)
    }

    /// The adapter's name and backend, for reports.
    pub fn adapter(&self) -> String {
        self.context.describe()
    }
}

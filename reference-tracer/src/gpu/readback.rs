//! What the GPU learned, read back into the core's structures, and guide samples drawn
//! on the GPU for the tests.

use glam::Vec3;

use super::{entry_point, GpuTracer};
use crate::directional_guide::DirectionalGuide;

impl GpuTracer {
    /// Reads what `guide` (the guide this tracer was built with) learned on the GPU back
    /// into it.
    pub fn download(&self, guide: &mut DirectionalGuide) -> Result<(), String> {
        self.guide.download(&self.context, self.host.as_ref(), &self.params, guide)
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
            wgpu::BindGroupEntry { binding: 10, resource: self.guide.positions.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 11, resource: self.guide.normals.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 12, resource: self.guide.index_table.as_entire_binding() },
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
        let words = self.context.copy_to_host(&samples)?;
        let sample = |c: &[u32]| [c[0], c[1], c[2], c[3]].map(f32::from_bits);
        Ok(words.chunks_exact(4).map(sample).take(count as usize).collect())
    }

    /// The adapter's name and backend, for reports.
    pub fn adapter(&self) -> String {
        self.context.describe()
    }
}

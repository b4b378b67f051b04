//! A [`HemisphereGrid`] on the GPU: its flat arrays uploaded as they are (f32 positions
//! and normals, Q as f32 bits, visit counts, CDF, Lambertian sums, the hash grid's bucket
//! table), updated in place by the shader, and read back into the same grid.

use std::sync::atomic::Ordering;

use guiding_core::{HemisphereGrid, HemisphereMapping, LearningRate};
use wgpu::util::DeviceExt;

/// What the GPU guide cannot do with `grid`'s settings, if anything.
pub fn unsupported(grid: &HemisphereGrid) -> Option<String> {
    let settings = grid.settings();
    if settings.layout.mapping != HemisphereMapping::Cylindrical {
        return Some("the concentric patch layout (use --mapping cylindrical)".into());
    }
    if settings.sampling_exponent != 1.0 {
        return Some("a sampling exponent other than 1".into());
    }
    if matches!(settings.update_rule.learning_rate, LearningRate::Global { .. }) {
        return Some("the global learning rate".into());
    }
    None
}

/// The grid's buffers on a device.
pub struct GuideBuffers {
    pub positions: wgpu::Buffer,
    pub normals: wgpu::Buffer,
    pub bucket_starts: wgpu::Buffer,
    pub q: wgpu::Buffer,
    pub patch_visits: wgpu::Buffer,
    pub probe_visits: wgpu::Buffer,
    pub cdf: wgpu::Buffer,
    pub lambertian_sums: wgpu::Buffer,
    pub patch_cos_integrals: wgpu::Buffer,
    pub built_visits: wgpu::Buffer,
}

fn bits(words: &[std::sync::atomic::AtomicU32]) -> Vec<u32> {
    words.iter().map(|w| w.load(Ordering::Relaxed)).collect()
}

/// One element where an array would be empty: bindings cannot be zero-sized.
fn padded<T: Default + Clone>(values: &[T]) -> Vec<T> {
    if values.is_empty() {
        vec![T::default()]
    } else {
        values.to_vec()
    }
}

const READ_WRITE: wgpu::BufferUsages =
    wgpu::BufferUsages::STORAGE.union(wgpu::BufferUsages::COPY_SRC).union(wgpu::BufferUsages::COPY_DST);

impl GuideBuffers {
    /// Uploads `grid`, or one-element placeholders for unguided renders.
    pub fn new(device: &wgpu::Device, grid: Option<&HemisphereGrid>) -> Self {
        let buffer = |label: &str, bytes: &[u8], usage: wgpu::BufferUsages| {
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor { label: Some(label), contents: bytes, usage })
        };
        let read = wgpu::BufferUsages::STORAGE;
        let floats = |values: &[glam::Vec3]| padded(&values.iter().flat_map(|v| v.to_array()).collect::<Vec<f32>>());
        let (positions, normals, buckets, q, patch_visits, probe_visits, cdf, sums, cosines) = match grid {
            Some(g) => (
                floats(g.probe_positions()),
                floats(g.probe_normals()),
                padded(g.lookup().bucket_starts()),
                padded(&bits(g.q_values())),
                padded(&bits(g.visit_counts())),
                padded(&bits(g.probe_visit_counts())),
                padded(g.cdf()),
                padded(&bits(g.lambertian_sums())),
                padded(g.patch_cos_integrals()),
            ),
            None => (vec![0.0], vec![0.0], vec![0, 0], vec![0], vec![0], vec![0], vec![0.0], vec![0], vec![0.0]),
        };
        // The CDFs uploaded are current: rebuild only what the first pass changes.
        let built = probe_visits.clone();
        Self {
            positions: buffer("probe positions", bytemuck::cast_slice(&positions), read),
            normals: buffer("probe normals", bytemuck::cast_slice(&normals), read),
            bucket_starts: buffer("bucket starts", bytemuck::cast_slice(&buckets), read),
            q: buffer("q", bytemuck::cast_slice(&q), READ_WRITE),
            patch_visits: buffer("patch visits", bytemuck::cast_slice(&patch_visits), READ_WRITE),
            probe_visits: buffer("probe visits", bytemuck::cast_slice(&probe_visits), READ_WRITE),
            cdf: buffer("cdf", bytemuck::cast_slice(&cdf), READ_WRITE),
            lambertian_sums: buffer("lambertian sums", bytemuck::cast_slice(&sums), READ_WRITE),
            patch_cos_integrals: buffer("patch cosine integrals", bytemuck::cast_slice(&cosines), read),
            built_visits: buffer("built visits", bytemuck::cast_slice(&built), READ_WRITE),
        }
    }
}

/// Stores learned Q and visit counts (read back from the GPU) into `grid`, then
/// rebuilds its sampling: the grid then holds exactly the GPU's learned state.
pub fn store_learned(grid: &mut HemisphereGrid, q: &[u32], patch_visits: &[u32], probe_visits: &[u32]) {
    for (word, &value) in grid.q_values().iter().zip(q) {
        word.store(value, Ordering::Relaxed);
    }
    for (word, &value) in grid.visit_counts().iter().zip(patch_visits) {
        word.store(value, Ordering::Relaxed);
    }
    for (word, &value) in grid.probe_visit_counts().iter().zip(probe_visits) {
        word.store(value, Ordering::Relaxed);
    }
    guiding_core::Guide::rebuild_sampling(grid);
}

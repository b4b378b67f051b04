// Lodestar's GPU path tracer: one invocation traces one pixel's path for one pass (a
// megakernel), the same estimators as the CPU tracer (integrator.rs): BSDF sampling,
// next-event estimation with the power heuristic, and guided sampling from a hemisphere
// grid or an irradiance volume uploaded in guiding-core's own flat layout, learning by
// Eq. (1) with compare-exchange float updates on atomic<u32>.

const PI: f32 = 3.14159265358979;
const INFINITY: f32 = 3.4e38;
const NO_LIGHT: u32 = 0xffffffffu;
const STACK_SIZE: u32 = 64u;
const MAX_VERTICES: u32 = 64u;

// The uniform block (Params) is generated from Rust (gpu/params.rs) ahead of these files.

struct Node {
    min: vec3<f32>,
    first: u32,
    max: vec3<f32>,
    count: u32,
};

struct Material {
    kind: u32,
    alpha: f32,
    ior: f32,
    fresnel: u32,
    albedo: vec4<f32>,
    emission: vec4<f32>,
    eta: vec4<f32>,
    k: vec4<f32>,
};

struct Light {
    v0: vec4<f32>,
    v1: vec4<f32>,
    v2: vec4<f32>,        // w: area
    emission: vec4<f32>,  // w: selection probability
};

struct Counters {
    paths: atomic<u32>,
    nonzero: atomic<u32>,
    rays: atomic<u32>,
    vertices: atomic<u32>,
};

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> nodes: array<Node>;
// Three per triangle in BVH leaf order: v0 (w: original index, bits), v1, v2.
@group(0) @binding(2) var<storage, read> triangles: array<vec4<f32>>;
// Per original triangle: the unit geometric normal (w: material index, bits).
@group(0) @binding(3) var<storage, read> triangle_info: array<vec4<f32>>;
// Per original triangle: its light index, or NO_LIGHT.
@group(0) @binding(4) var<storage, read> light_of_triangle: array<u32>;
@group(0) @binding(5) var<storage, read> materials: array<Material>;
@group(0) @binding(6) var<storage, read> lights: array<Light>;
@group(0) @binding(7) var<storage, read> light_cdf: array<f32>;
@group(0) @binding(8) var<storage, read_write> pass_image: array<vec4<f32>>;
@group(0) @binding(9) var<storage, read_write> counters: Counters;

// The directional guide, in guiding-core's own flat layout (HemisphereGrid's or
// IrradianceVolume's slices, uploaded unchanged): region r's patch k is entry r·N + k.
// A region is a probe of the grid (sorted by bucket) or a leaf of the volume. The
// mixture (GaussianMixture's lobe table and batch words) reuses `cdf` for its lobes and
// `q` for its batch sums; N is then its lobe count.
@group(0) @binding(10) var<storage, read> probe_positions: array<f32>;
@group(0) @binding(11) var<storage, read> probe_normals: array<f32>;
// The grid: its hash grid's bucket starts. The volume: its octree's nodes.
@group(0) @binding(12) var<storage, read> index_table: array<u32>;
@group(0) @binding(13) var<storage, read_write> q: array<atomic<u32>>;
@group(0) @binding(14) var<storage, read_write> patch_visits: array<atomic<u32>>;
@group(0) @binding(15) var<storage, read_write> region_visits: array<atomic<u32>>;
@group(0) @binding(16) var<storage, read_write> cdf: array<f32>;
// The grid: each probe's Lambertian sum Σ Q·∫cos. The volume: each leaf's nine
// spherical-harmonic coefficients of Q.
@group(0) @binding(17) var<storage, read_write> integral_terms: array<atomic<u32>>;
// The grid: each patch's ∫cos dω. The volume: each patch's nine ∫Y_lm dω.
@group(0) @binding(18) var<storage, read> patch_weights: array<f32>;
// Each region's visit count when its CDF was last built (the GPU's own bookkeeping).
@group(0) @binding(19) var<storage, read_write> built_visits: array<u32>;
// Directions drawn by `sample_guide` (tests of the GPU sampler).
@group(0) @binding(20) var<storage, read_write> guide_samples: array<vec4<f32>>;

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

const METHOD_PT: u32 = 0u;
const METHOD_NEE: u32 = 1u;
const METHOD_GUIDED: u32 = 2u;
const METHOD_GUIDED_NEE: u32 = 3u;

const DIFFUSE: u32 = 0u;
const CONDUCTOR: u32 = 1u;
const DIELECTRIC: u32 = 2u;
const THIN_DIELECTRIC: u32 = 3u;

const GUIDE_HEMISPHERE: u32 = 0u;
const GUIDE_VOLUME: u32 = 1u;
const GUIDE_MIXTURE: u32 = 2u;

struct Params {
    width: u32,
    height: u32,
    pass_index: u32,
    seed: u32,
    max_depth: u32,
    rr_depth: u32,
    method: u32,
    light_count: u32,
    eye: vec4<f32>,
    forward: vec4<f32>,   // w: tan(fov_y / 2)
    right: vec4<f32>,
    up: vec4<f32>,
    environment: vec4<f32>, // rgb radiance; w: probability that NEE picks the environment
    scene: vec4<f32>,       // x: ray epsilon (scene-relative), y: guide probability
    guide: vec4<u32>,       // x: guide present, y: learn, z: regions (probes or leaves), w: patches
    guide_shape: vec4<u32>, // x: patch rows (cos θ bands), y: patch columns (φ sectors), z: buckets, w: search rings
    guide_lookup: vec4<f32>, // xyz: hash grid origin, w: cell size
    guide_rule: vec4<f32>,  // x: floor, y: cos of the largest normal angle, z: learning rate kind, w: its parameter
    volume_grid: vec4<u32>, // xyz: the volume's or mixture's grid cells per axis, w: guide kind (GUIDE_*)
    volume_low: vec4<f32>,  // xyz: the grid's low corner
    volume_scale: vec4<f32>, // xyz: the grid's cells per unit length
    sample_normal: vec4<f32>, // xyz: the normal `sample_guide` samples a volume leaf about
};

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

// ---------------------------------------------------------------------------------
// Random numbers: a 32-bit PCG per pixel and pass, seeded by hashing both (the GPU has
// no 64-bit integers).

var<private> rng_state: u32;

fn pcg_hash(v: u32) -> u32 {
    let state = v * 747796405u + 2891336453u;
    let word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
    return (word >> 22u) ^ word;
}

fn next_f32() -> f32 {
    rng_state = rng_state * 747796405u + 2891336453u;
    let state = rng_state;
    let word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
    // 24 random bits, as the CPU's: [0, 1) exactly.
    return f32(((word >> 22u) ^ word) >> 8u) * (1.0 / 16777216.0);
}

fn next_vec2() -> vec2<f32> {
    let a = next_f32();
    return vec2<f32>(a, next_f32());
}

// ---------------------------------------------------------------------------------
// Geometry.

struct Hit {
    t: f32,
    primitive: u32,
    b1: f32,
    b2: f32,
};

struct ShearedRay {
    origin: vec3<f32>,
    row_x: vec3<f32>,
    row_y: vec3<f32>,
    row_z: vec3<f32>,
    shear_z: f32,
};

fn axis(k: u32) -> vec3<f32> {
    return select(select(vec3<f32>(0.0, 0.0, 1.0), vec3<f32>(0.0, 1.0, 0.0), k == 1u), vec3<f32>(1.0, 0.0, 0.0), k == 0u);
}

fn component(v: vec3<f32>, k: u32) -> f32 {
    return select(select(v.z, v.y, k == 1u), v.x, k == 0u);
}

// Woop, Benthin & Wald's watertight test (guiding-obvhs's ShearedRay, without the f64
// recomputation of edge functions that round to zero, which WGSL cannot do).
fn shear(origin: vec3<f32>, direction: vec3<f32>) -> ShearedRay {
    let a = abs(direction);
    var kz = 0u;
    if (a.y > a.x && a.y >= a.z) { kz = 1u; } else if (a.z > a.x && a.z > a.y) { kz = 2u; }
    var kx = (kz + 1u) % 3u;
    var ky = (kx + 1u) % 3u;
    let dz = component(direction, kz);
    if (dz < 0.0) { let swap = kx; kx = ky; ky = swap; }
    let sx = component(direction, kx) / dz;
    let sy = component(direction, ky) / dz;
    var s: ShearedRay;
    s.origin = origin;
    s.row_x = axis(kx) - sx * axis(kz);
    s.row_y = axis(ky) - sy * axis(kz);
    s.row_z = axis(kz);
    s.shear_z = 1.0 / dz;
    return s;
}

// Ray parameter and barycentrics (b1, b2) of a hit with t_min < t <= t_max, or t < 0.
fn intersect_triangle(s: ShearedRay, slot: u32, t_min: f32, t_max: f32) -> vec3<f32> {
    let a = triangles[3u * slot].xyz - s.origin;
    let b = triangles[3u * slot + 1u].xyz - s.origin;
    let c = triangles[3u * slot + 2u].xyz - s.origin;
    let pa = vec2<f32>(dot(s.row_x, a), dot(s.row_y, a));
    let pb = vec2<f32>(dot(s.row_x, b), dot(s.row_y, b));
    let pc = vec2<f32>(dot(s.row_x, c), dot(s.row_y, c));
    let u = pc.x * pb.y - pc.y * pb.x;
    let v = pa.x * pc.y - pa.y * pc.x;
    let w = pb.x * pa.y - pb.y * pa.x;
    if ((u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0)) { return vec3<f32>(-1.0, 0.0, 0.0); }
    let determinant = u + v + w;
    if (determinant == 0.0) { return vec3<f32>(-1.0, 0.0, 0.0); }
    let inverse = 1.0 / determinant;
    let t = s.shear_z * (u * dot(s.row_z, a) + v * dot(s.row_z, b) + w * dot(s.row_z, c)) * inverse;
    if (!(t > t_min && t <= t_max)) { return vec3<f32>(-1.0, 0.0, 0.0); }
    return vec3<f32>(t, v * inverse, w * inverse);
}

// Entry distance of the slab test, or INFINITY for a miss. Tiny direction components
// are replaced by ±1e-20 (like obvhs), so the reciprocal stays finite.
fn box_entry(node: Node, origin: vec3<f32>, inverse: vec3<f32>, t_min: f32, t_max: f32) -> f32 {
    let t0 = (node.min - origin) * inverse;
    let t1 = (node.max - origin) * inverse;
    let near = min(t0, t1);
    let far = max(t0, t1);
    let enter = max(max(near.x, near.y), max(near.z, t_min));
    let leave = min(min(far.x, far.y), min(far.z, t_max));
    return select(INFINITY, enter, enter <= leave);
}

fn safe_inverse(d: vec3<f32>) -> vec3<f32> {
    let tiny = vec3<f32>(1e-20);
    let magnitude = max(abs(d), tiny);
    return 1.0 / select(magnitude, -magnitude, d < vec3<f32>(0.0));
}

// The closest hit along origin + t·direction, t_min < t < t_max; primitive = NO_LIGHT
// when nothing is hit. Ties go to the lower original index, as on the CPU.
fn intersect(origin: vec3<f32>, direction: vec3<f32>, t_min: f32, t_max: f32) -> Hit {
    var best: Hit;
    best.t = t_max;
    best.primitive = NO_LIGHT;
    if (arrayLength(&nodes) == 0u) { return best; }
    let s = shear(origin, direction);
    let inverse = safe_inverse(direction);
    var stack: array<u32, STACK_SIZE>;
    var top = 0u;
    stack[0] = 0u;
    top = 1u;
    loop {
        if (top == 0u) { break; }
        top -= 1u;
        let node = nodes[stack[top]];
        if (box_entry(node, origin, inverse, t_min, best.t) == INFINITY) { continue; }
        if (node.count > 0u) {
            for (var slot = node.first; slot < node.first + node.count; slot += 1u) {
                let hit = intersect_triangle(s, slot, t_min, best.t);
                let index = bitcast<u32>(triangles[3u * slot].w);
                if (hit.x > 0.0 && (hit.x < best.t || (hit.x == best.t && index < best.primitive))) {
                    best.t = hit.x;
                    best.primitive = index;
                    best.b1 = hit.y;
                    best.b2 = hit.z;
                }
            }
        } else if (top + 2u <= STACK_SIZE) {
            // Nearer child last, so it is visited first.
            let left = nodes[node.first];
            let right = nodes[node.first + 1u];
            let t_left = box_entry(left, origin, inverse, t_min, best.t);
            let t_right = box_entry(right, origin, inverse, t_min, best.t);
            if (t_left < t_right) {
                stack[top] = node.first + 1u;
                stack[top + 1u] = node.first;
            } else {
                stack[top] = node.first;
                stack[top + 1u] = node.first + 1u;
            }
            top += 2u;
        }
    }
    if (best.primitive != NO_LIGHT && best.t >= t_max) { best.primitive = NO_LIGHT; }
    return best;
}

// Whether anything lies strictly inside the segment (any hit).
fn occluded(origin: vec3<f32>, direction: vec3<f32>, t_max: f32) -> bool {
    if (arrayLength(&nodes) == 0u) { return false; }
    let s = shear(origin, direction);
    let inverse = safe_inverse(direction);
    var stack: array<u32, STACK_SIZE>;
    stack[0] = 0u;
    var top = 1u;
    loop {
        if (top == 0u) { break; }
        top -= 1u;
        let node = nodes[stack[top]];
        if (box_entry(node, origin, inverse, 0.0, t_max) == INFINITY) { continue; }
        if (node.count > 0u) {
            for (var slot = node.first; slot < node.first + node.count; slot += 1u) {
                let hit = intersect_triangle(s, slot, 0.0, t_max);
                if (hit.x > 0.0 && hit.x < t_max) { return true; }
            }
        } else if (top + 2u <= STACK_SIZE) {
            stack[top] = node.first;
            stack[top + 1u] = node.first + 1u;
            top += 2u;
        }
    }
    return false;
}

// ---------------------------------------------------------------------------------
// Frames and sampling.

struct Frame {
    tangent: vec3<f32>,
    bitangent: vec3<f32>,
    normal: vec3<f32>,
};

// guiding-core's Frame::from_normal (Duff et al.).
fn frame_from_normal(n: vec3<f32>) -> Frame {
    let sign = select(-1.0, 1.0, n.z >= 0.0);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    var f: Frame;
    f.tangent = vec3<f32>(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
    f.bitangent = vec3<f32>(b, sign + n.y * n.y * a, -n.y);
    f.normal = n;
    return f;
}

fn to_local(f: Frame, v: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(dot(v, f.tangent), dot(v, f.bitangent), dot(v, f.normal));
}

fn to_world(f: Frame, v: vec3<f32>) -> vec3<f32> {
    return f.tangent * v.x + f.bitangent * v.y + f.normal * v.z;
}

// The unit vector with z = `z` and azimuth `phi` about the z axis.
fn spherical_direction(z: f32, phi: f32) -> vec3<f32> {
    let r = sqrt(max(1.0 - z * z, 0.0));
    return vec3<f32>(r * cos(phi), r * sin(phi), z);
}

fn cosine_hemisphere(u: vec2<f32>) -> vec3<f32> {
    let r = sqrt(u.x);
    let phi = 2.0 * PI * u.y;
    return vec3<f32>(r * cos(phi), r * sin(phi), sqrt(max(1.0 - u.x, 0.0)));
}

fn power_heuristic(pdf: f32, other: f32) -> f32 {
    let a = pdf * pdf;
    let b = other * other;
    if (a + b > 0.0 && a < INFINITY) { return a / (a + b); }
    return select(0.0, 1.0, a >= INFINITY);
}

fn luminance(c: vec3<f32>) -> f32 {
    return dot(c, vec3<f32>(0.2126, 0.7152, 0.0722));
}

// ---------------------------------------------------------------------------------
// Materials (material/*.rs): f·cos, pdf and sampling in the local frame (z = normal
// facing the viewer; for dielectrics the outside).

fn fresnel_dielectric(cos_incident: f32, eta: f32) -> f32 {
    let sin2_t = max(1.0 - cos_incident * cos_incident, 0.0) / (eta * eta);
    if (sin2_t >= 1.0) { return 1.0; }
    let cos_t = sqrt(1.0 - sin2_t);
    let parallel = (eta * cos_incident - cos_t) / (eta * cos_incident + cos_t);
    let perpendicular = (cos_incident - eta * cos_t) / (cos_incident + eta * cos_t);
    return 0.5 * (parallel * parallel + perpendicular * perpendicular);
}

fn fresnel_conductor(cos_incident: f32, eta: vec3<f32>, k: vec3<f32>) -> vec3<f32> {
    let c = clamp(cos_incident, 0.0, 1.0);
    let cos2 = vec3<f32>(c * c);
    let sin2 = vec3<f32>(1.0) - cos2;
    let eta2 = eta * eta;
    let k2 = k * k;
    let t0 = eta2 - k2 - sin2;
    let a2b2 = sqrt(max(t0 * t0 + 4.0 * eta2 * k2, vec3<f32>(0.0)));
    let t1 = a2b2 + cos2;
    let a = sqrt(max(0.5 * (a2b2 + t0), vec3<f32>(0.0)));
    let t2 = 2.0 * c * a;
    let rs = (t1 - t2) / max(t1 + t2, vec3<f32>(1e-30));
    let t3 = cos2 * a2b2 + sin2 * sin2;
    let t4 = t2 * sin2;
    let rp = rs * (t3 - t4) / max(t3 + t4, vec3<f32>(1e-30));
    return clamp(0.5 * (rp + rs), vec3<f32>(0.0), vec3<f32>(1.0));
}

fn ggx_d(alpha: f32, h: vec3<f32>) -> f32 {
    let a2 = alpha * alpha;
    let d = h.z * h.z * (a2 - 1.0) + 1.0;
    return a2 / (PI * d * d);
}

fn ggx_lambda(alpha: f32, w: vec3<f32>) -> f32 {
    let cos2 = w.z * w.z;
    if (cos2 <= 0.0) { return INFINITY; }
    let tan2 = max(1.0 - cos2, 0.0) / cos2;
    return 0.5 * (sqrt(1.0 + alpha * alpha * tan2) - 1.0);
}

fn ggx_reflection_pdf(alpha: f32, wo: vec3<f32>, wi: vec3<f32>) -> f32 {
    if (wo.z <= 0.0 || wi.z <= 0.0) { return 0.0; }
    let h = normalize(wo + wi);
    return ggx_d(alpha, h) / ((1.0 + ggx_lambda(alpha, wo)) * 4.0 * wo.z);
}

// Heitz 2018: a visible normal, reflected; returns wi (z <= 0 for a failed draw).
fn ggx_sample(alpha: f32, wo: vec3<f32>, u: vec2<f32>) -> vec3<f32> {
    let vh = normalize(vec3<f32>(alpha * wo.x, alpha * wo.y, wo.z));
    let length2 = vh.x * vh.x + vh.y * vh.y;
    let t1 = select(vec3<f32>(1.0, 0.0, 0.0), vec3<f32>(-vh.y, vh.x, 0.0) / sqrt(length2), length2 > 0.0);
    let t2 = cross(vh, t1);
    let r = sqrt(u.x);
    let phi = 2.0 * PI * u.y;
    let p1 = r * cos(phi);
    let s = 0.5 * (1.0 + vh.z);
    let p2 = (1.0 - s) * sqrt(max(1.0 - p1 * p1, 0.0)) + s * r * sin(phi);
    let nh = t1 * p1 + t2 * p2 + vh * sqrt(max(1.0 - p1 * p1 - p2 * p2, 0.0));
    let h = normalize(vec3<f32>(alpha * nh.x, alpha * nh.y, max(nh.z, 1e-6)));
    return 2.0 * dot(wo, h) * h - wo;
}

fn conductor_fresnel(m: Material, cos_incident: f32) -> vec3<f32> {
    if (m.fresnel == 0u) { return vec3<f32>(1.0); }
    return fresnel_conductor(cos_incident, m.eta.xyz, m.k.xyz);
}

fn is_delta(m: Material) -> bool {
    return m.kind == DIELECTRIC || m.kind == THIN_DIELECTRIC || (m.kind == CONDUCTOR && m.alpha == 0.0);
}

fn bsdf_eval(m: Material, wo: vec3<f32>, wi: vec3<f32>) -> vec3<f32> {
    if (wo.z <= 0.0 || wi.z <= 0.0) { return vec3<f32>(0.0); }
    if (m.kind == DIFFUSE) { return m.albedo.xyz * (wi.z / PI); }
    if (m.kind == CONDUCTOR && m.alpha > 0.0) {
        let alpha = max(m.alpha, 1e-4);
        let h = normalize(wo + wi);
        let g2 = 1.0 / (1.0 + ggx_lambda(alpha, wo) + ggx_lambda(alpha, wi));
        return m.albedo.xyz * conductor_fresnel(m, dot(wo, h)) * (ggx_d(alpha, h) * g2 / (4.0 * wo.z));
    }
    return vec3<f32>(0.0);
}

fn bsdf_pdf(m: Material, wo: vec3<f32>, wi: vec3<f32>) -> f32 {
    if (m.kind == DIFFUSE) { return select(0.0, max(wi.z, 0.0) / PI, wo.z > 0.0); }
    if (m.kind == CONDUCTOR && m.alpha > 0.0) { return ggx_reflection_pdf(max(m.alpha, 1e-4), wo, wi); }
    return 0.0;
}

struct BsdfSample {
    wi: vec3<f32>,
    weight: vec3<f32>,
    pdf: f32,
    ok: bool,
};

fn bsdf_sample(m: Material, wo: vec3<f32>, u: vec2<f32>, u_lobe: f32) -> BsdfSample {
    var s: BsdfSample;
    s.ok = false;
    if (m.kind == DIFFUSE) {
        if (wo.z <= 0.0) { return s; }
        s.wi = cosine_hemisphere(u);
        s.pdf = s.wi.z / PI;
        s.weight = m.albedo.xyz;
        s.ok = s.pdf > 0.0;
        return s;
    }
    if (m.kind == CONDUCTOR) {
        if (wo.z <= 0.0) { return s; }
        if (m.alpha == 0.0) {
            s.wi = vec3<f32>(-wo.x, -wo.y, wo.z);
            s.weight = m.albedo.xyz * conductor_fresnel(m, wo.z);
            s.pdf = 1.0;
            s.ok = true;
            return s;
        }
        let alpha = max(m.alpha, 1e-4);
        let wi = ggx_sample(alpha, wo, u);
        if (wi.z <= 0.0) { return s; }
        let pdf = ggx_reflection_pdf(alpha, wo, wi);
        if (!(pdf > 0.0 && pdf < INFINITY)) { return s; }
        let h = normalize(wo + wi);
        let ratio = (1.0 + ggx_lambda(alpha, wo)) / (1.0 + ggx_lambda(alpha, wo) + ggx_lambda(alpha, wi));
        s.wi = wi;
        s.pdf = pdf;
        s.weight = m.albedo.xyz * conductor_fresnel(m, dot(wo, h)) * ratio;
        s.ok = true;
        return s;
    }
    if (wo.z == 0.0) { return s; }
    if (m.kind == THIN_DIELECTRIC) {
        let r = fresnel_dielectric(abs(wo.z), m.ior);
        let reflectance = 2.0 * r / (1.0 + r);
        s.weight = vec3<f32>(1.0);
        s.ok = true;
        if (u_lobe < reflectance) {
            s.wi = vec3<f32>(-wo.x, -wo.y, wo.z);
            s.pdf = reflectance;
        } else {
            s.wi = -wo;
            s.pdf = 1.0 - reflectance;
        }
        return s;
    }
    // Smooth glass.
    let entering = wo.z > 0.0;
    let eta = select(1.0 / m.ior, m.ior, entering);
    let cos_i = abs(wo.z);
    let reflectance = fresnel_dielectric(cos_i, eta);
    s.ok = true;
    if (u_lobe < reflectance) {
        s.wi = vec3<f32>(-wo.x, -wo.y, wo.z);
        s.weight = vec3<f32>(1.0);
        s.pdf = reflectance;
        return s;
    }
    let sin2_t = max(1.0 - cos_i * cos_i, 0.0) / (eta * eta);
    let cos_t = sqrt(max(1.0 - sin2_t, 0.0));
    s.wi = normalize(vec3<f32>(-wo.x / eta, -wo.y / eta, select(cos_t, -cos_t, entering)));
    s.weight = vec3<f32>(1.0 / (eta * eta));
    s.pdf = 1.0 - reflectance;
    return s;
}

// ---------------------------------------------------------------------------------
// Lights.

// guiding-core's sample_cdf: the index k with cdf[k-1] <= u < cdf[k].
fn sample_light_cdf(u: f32) -> u32 {
    var low = 0u;
    var high = params.light_count;
    while (low < high) {
        let middle = (low + high) / 2u;
        if (light_cdf[middle] <= u) { low = middle + 1u; } else { high = middle; }
    }
    return min(low, params.light_count - 1u);
}

// Density per steradian with which NEE produces the direction from `from` to `point`
// on light `light` (normal `normal`), selection included.
fn light_pdf(light: u32, origin: vec3<f32>, point: vec3<f32>, normal: vec3<f32>) -> f32 {
    let to_light = point - origin;
    let distance2 = dot(to_light, to_light);
    let cos_light = -dot(normal, to_light) / sqrt(distance2);
    if (cos_light <= 0.0) { return 0.0; }
    let l = lights[light];
    return (1.0 - params.environment.w) * l.emission.w * distance2 / (cos_light * l.v2.w);
}

fn epsilon_at(point: vec3<f32>) -> f32 {
    let a = abs(point);
    return params.scene.x + 1e-6 * max(max(a.x, a.y), a.z);
}

fn spawn(point: vec3<f32>, normal: vec3<f32>, direction: vec3<f32>) -> vec3<f32> {
    let side = select(-1.0, 1.0, dot(normal, direction) >= 0.0);
    return point + normal * (side * epsilon_at(point));
}

struct Shading {
    frame: Frame,
    geometric: vec3<f32>,
};

fn shading_frame(m: Material, geometric_normal: vec3<f32>, wo: vec3<f32>) -> Shading {
    var s: Shading;
    if (m.kind == DIELECTRIC || m.kind == THIN_DIELECTRIC) {
        s.frame = frame_from_normal(geometric_normal);
        s.geometric = geometric_normal;
        return s;
    }
    let n = select(geometric_normal, -geometric_normal, dot(geometric_normal, wo) < 0.0);
    s.frame = frame_from_normal(n);
    s.geometric = n;
    return s;
}


// ---------------------------------------------------------------------------------
// The hemisphere grid (guiding-core's hemisphere/): lookup, sampling, pdf, Eq. (1).

const NO_PROBE: u32 = 0xffffffffu;
const MAX_CELL: i32 = 1048576;
const MIN_SAMPLED_COS: f32 = 1e-5;

fn probe_position(p: u32) -> vec3<f32> {
    return vec3<f32>(probe_positions[3u * p], probe_positions[3u * p + 1u], probe_positions[3u * p + 2u]);
}

fn probe_normal(p: u32) -> vec3<f32> {
    return vec3<f32>(probe_normals[3u * p], probe_normals[3u * p + 1u], probe_normals[3u * p + 2u]);
}

fn floor_i32(x: f32) -> i32 {
    return i32(clamp(floor(x), -2147483520.0, 2147483520.0));
}

fn cell_of(p: vec3<f32>) -> vec3<i32> {
    let c = (p - params.guide_lookup.xyz) / params.guide_lookup.w;
    return clamp(vec3<i32>(floor_i32(c.x), floor_i32(c.y), floor_i32(c.z)), vec3<i32>(-MAX_CELL), vec3<i32>(MAX_CELL));
}

fn bucket(cell: vec3<i32>) -> u32 {
    let hash = (u32(cell.x) * 73856093u) ^ (u32(cell.y) * 19349663u) ^ (u32(cell.z) * 83492791u);
    return hash & (params.guide_shape.z - 1u);
}

struct Nearest {
    probe: u32,
    distance2: f32,
};

fn visit_cell(cell: vec3<i32>, query: vec3<f32>, normal: vec3<f32>, best: Nearest) -> Nearest {
    var result = best;
    let b = bucket(cell);
    for (var p = index_table[b]; p < index_table[b + 1u]; p += 1u) {
        let d = probe_position(p) - query;
        let d2 = dot(d, d);
        if ((result.probe == NO_PROBE || d2 < result.distance2) && dot(probe_normal(p), normal) >= params.guide_rule.y) {
            result.probe = p;
            result.distance2 = d2;
        }
    }
    return result;
}

// ProbeLookup::nearest: the nearest probe whose normal is within the largest angle of
// `normal`, within the search rings; NO_PROBE otherwise.
fn locate(query: vec3<f32>, normal: vec3<f32>) -> u32 {
    var best: Nearest;
    best.probe = NO_PROBE;
    best.distance2 = INFINITY;
    let cell_size = params.guide_lookup.w;
    let scaled = (query - params.guide_lookup.xyz) / cell_size;
    let center = cell_of(query);
    let fraction = clamp(scaled - vec3<f32>(center), vec3<f32>(0.0), vec3<f32>(1.0));
    best = visit_cell(center, query, normal, best);
    if (best.probe != NO_PROBE) {
        let near = min(fraction, vec3<f32>(1.0) - fraction);
        let margin = min(min(near.x, near.y), near.z) * cell_size;
        if (best.distance2 <= margin * margin) { return best.probe; }
    }
    let step = select(vec3<i32>(1), vec3<i32>(-1), fraction < vec3<f32>(0.5));
    for (var corner = 1; corner < 8; corner += 1) {
        let offset = vec3<i32>(corner & 1, (corner >> 1u) & 1, corner >> 2u) * step;
        best = visit_cell(center + offset, query, normal, best);
    }
    if (best.probe != NO_PROBE) {
        let half = 0.5 * cell_size;
        if (best.distance2 <= half * half) { return best.probe; }
    }
    for (var ring = 1; ring <= i32(params.guide_shape.w); ring += 1) {
        for (var dz = -ring; dz <= ring; dz += 1) {
            for (var dy = -ring; dy <= ring; dy += 1) {
                for (var dx = -ring; dx <= ring; dx += 1) {
                    if (max(max(abs(dx), abs(dy)), abs(dz)) == ring) {
                        best = visit_cell(center + vec3<i32>(dx, dy, dz), query, normal, best);
                    }
                }
            }
        }
        if (best.probe != NO_PROBE) {
            let reach = f32(ring) * cell_size;
            if (best.distance2 <= reach * reach) { return best.probe; }
        }
    }
    return NO_PROBE;
}

fn patch_solid_angle() -> f32 {
    return 2.0 * PI / f32(params.guide.w);
}

// PatchLayout::patch_of for the cylindrical mapping; N (none) below the horizon.
fn patch_of(local: vec3<f32>) -> u32 {
    if (!(local.z >= 0.0)) { return params.guide.w; }
    var phi = atan2(local.y, local.x);
    if (phi < 0.0) { phi += 2.0 * PI; }
    let rows = params.guide_shape.x;
    let columns = params.guide_shape.y;
    let iu = min(u32(clamp(local.z, 0.0, 1.0) * f32(rows)), rows - 1u);
    let iv = min(u32(phi * (0.5 / PI) * f32(columns)), columns - 1u);
    return iu * columns + iv;
}

fn direction_in_patch(entry: u32, xi: vec2<f32>) -> vec3<f32> {
    let rows = params.guide_shape.x;
    let columns = params.guide_shape.y;
    let uv = vec2<f32>((f32(entry / columns) + xi.x) / f32(rows), (f32(entry % columns) + xi.y) / f32(columns));
    let d = spherical_direction(clamp(uv.x, 0.0, 1.0), 2.0 * PI * uv.y);
    if (d.z >= MIN_SAMPLED_COS) { return d; }
    let planar = sqrt(d.x * d.x + d.y * d.y);
    let scale = sqrt(1.0 - MIN_SAMPLED_COS * MIN_SAMPLED_COS) / planar;
    return vec3<f32>(d.x * scale, d.y * scale, MIN_SAMPLED_COS);
}

fn patch_probability(region: u32, entry: u32) -> f32 {
    let base = region * params.guide.w;
    let low = select(0.0, cdf[base + entry - 1u], entry > 0u);
    return cdf[base + entry] - low;
}

struct CdfSample {
    entry: u32,
    rest: f32,
};

// sample_cdf over region `region`'s patches: the patch, and `u` rescaled inside it.
fn invert_cdf(region: u32, u: f32) -> CdfSample {
    let n = params.guide.w;
    let base = region * n;
    var low = 0u;
    var high = n;
    while (low < high) {
        let middle = (low + high) / 2u;
        if (cdf[base + middle] <= u) { low = middle + 1u; } else { high = middle; }
    }
    let entry = min(low, n - 1u);
    let start = select(0.0, cdf[base + entry - 1u], entry > 0u);
    let width = cdf[base + entry] - start;
    var s: CdfSample;
    s.entry = entry;
    s.rest = clamp(select(0.0, (u - start) / width, width > 0.0), 0.0, 0.99999994);
    return s;
}

struct GuideSample {
    wi: vec3<f32>,
    pdf: f32,
};

fn grid_pdf(probe: u32, wi: vec3<f32>) -> f32 {
    let entry = patch_of(to_local(frame_from_normal(probe_normal(probe)), wi));
    if (entry >= params.guide.w) { return 0.0; }
    return patch_probability(probe, entry) / patch_solid_angle();
}

fn grid_sample(probe: u32, u: vec2<f32>) -> GuideSample {
    let c = invert_cdf(probe, u.x);
    var s: GuideSample;
    s.wi = to_world(frame_from_normal(probe_normal(probe)), direction_in_patch(c.entry, vec2<f32>(c.rest, u.y)));
    s.pdf = patch_probability(probe, c.entry) / patch_solid_angle();
    return s;
}

// ---------------------------------------------------------------------------------
// The irradiance volume (guiding-core's volume/): leaf lookup down the octree, the
// whole sphere in equal-area patches in world axes, sampling folded onto the normal's
// hemisphere, and the Lambertian integral from each leaf's spherical harmonics.

const LEAF_BIT: u32 = 0x80000000u;
const MAX_TREE_DEPTH: u32 = 32u;

// CellGrid (the volume's and the mixture's): `p` in cell units from the low corner, the
// cell holding it (the nearest one outside) and that cell's index.
struct GridCell {
    scaled: vec3<f32>,
    cell: vec3<i32>,
    index: u32,
}

fn grid_cell(p: vec3<f32>) -> GridCell {
    let resolution = vec3<i32>(params.volume_grid.xyz);
    var g: GridCell;
    g.scaled = max((p - params.volume_low.xyz) * params.volume_scale.xyz, vec3<f32>(0.0));
    g.cell = min(vec3<i32>(g.scaled), resolution - vec3<i32>(1));
    g.index = u32((g.cell.z * resolution.y + g.cell.y) * resolution.x + g.cell.x);
    return g;
}

// IrradianceVolume::leaf_at: the grid cell holding `p` (the nearest one outside), then
// down by octants; NO_PROBE for a non-finite point.
fn volume_leaf(p: vec3<f32>) -> u32 {
    if (!all(abs(p) < vec3<f32>(INFINITY))) { return NO_PROBE; }
    let g = grid_cell(p);
    var offset = clamp(g.scaled - vec3<f32>(g.cell), vec3<f32>(0.0), vec3<f32>(1.0));
    var entry = index_table[g.index];
    for (var depth = 0u; depth < MAX_TREE_DEPTH && (entry & LEAF_BIT) == 0u; depth += 1u) {
        let upper = offset >= vec3<f32>(0.5);
        let octant = select(0u, 1u, upper.x) | select(0u, 2u, upper.y) | select(0u, 4u, upper.z);
        offset = offset * 2.0 - select(vec3<f32>(0.0), vec3<f32>(1.0), upper);
        entry = index_table[entry + octant];
    }
    if ((entry & LEAF_BIT) == 0u) { return NO_PROBE; }
    return entry & ~LEAF_BIT;
}

// SphereLayout::patch_of: bands of z, sectors of φ about the world z axis.
fn sphere_patch_of(direction: vec3<f32>) -> u32 {
    let d = normalize(direction);
    let bands = params.guide_shape.x;
    let sectors = params.guide_shape.y;
    let band = min(u32((d.z + 1.0) * 0.5 * f32(bands)), bands - 1u);
    var phi = atan2(d.y, d.x);
    if (phi < 0.0) { phi += 2.0 * PI; }
    let sector = min(u32(phi * (0.5 / PI) * f32(sectors)), sectors - 1u);
    return band * sectors + sector;
}

// SphereLayout::direction_in_patch: uniform in solid angle inside the patch.
fn sphere_direction_in_patch(entry: u32, u: vec2<f32>) -> vec3<f32> {
    let bands = params.guide_shape.x;
    let sectors = params.guide_shape.y;
    let z = clamp(-1.0 + 2.0 * (f32(entry / sectors) + u.x) / f32(bands), -1.0, 1.0);
    return spherical_direction(z, 2.0 * PI * (f32(entry % sectors) + u.y) / f32(sectors));
}

fn mirror(d: vec3<f32>, n: vec3<f32>) -> vec3<f32> {
    return normalize(d - 2.0 * dot(d, n) * n);
}

// guiding-core's fold_onto_hemisphere: below the surface mirrored, cos θ ≥ MIN_SAMPLED_COS.
fn fold_onto_hemisphere(direction: vec3<f32>, normal: vec3<f32>) -> vec3<f32> {
    var d = direction;
    if (dot(d, normal) < 0.0) { d = mirror(d, normal); }
    let cos_theta = dot(d, normal);
    if (cos_theta < MIN_SAMPLED_COS) { d = normalize(d + (MIN_SAMPLED_COS - cos_theta) * normal); }
    return d;
}

fn sphere_pdf(leaf: u32, d: vec3<f32>) -> f32 {
    return patch_probability(leaf, sphere_patch_of(d)) * f32(params.guide.w) / (4.0 * PI);
}

// VolumeDistribution::pdf: p(ω) + p(mirror ω) above the surface, 0 below.
fn volume_pdf(leaf: u32, normal: vec3<f32>, wi: vec3<f32>) -> f32 {
    if (!(dot(wi, normal) >= 0.0)) { return 0.0; }
    return sphere_pdf(leaf, wi) + sphere_pdf(leaf, mirror(wi, normal));
}

fn volume_sample(leaf: u32, normal: vec3<f32>, u: vec2<f32>) -> GuideSample {
    let c = invert_cdf(leaf, u.x);
    let d = fold_onto_hemisphere(sphere_direction_in_patch(c.entry, vec2<f32>(c.rest, u.y)), normal);
    var s: GuideSample;
    s.wi = d;
    s.pdf = volume_pdf(leaf, normal, d);
    return s;
}

// The nine real spherical harmonics of order ≤ 2 at unit `d` (irradiance_sh.rs).
fn sh_basis(d: vec3<f32>) -> array<f32, 9> {
    return array<f32, 9>(
        0.282095,
        0.488603 * d.y,
        0.488603 * d.z,
        0.488603 * d.x,
        1.092548 * d.x * d.y,
        1.092548 * d.y * d.z,
        0.315392 * (3.0 * d.z * d.z - 1.0),
        1.092548 * d.x * d.z,
        0.546274 * (d.x * d.x - d.y * d.y),
    );
}

// ∫ Q·max(0, n·ω)/π dω from leaf `leaf`'s coefficients (Ramamoorthi–Hanrahan's band
// weights Â_l/π), clamped at 0.
fn sh_cosine_integral(leaf: u32, normal: vec3<f32>) -> f32 {
    let weights = array<f32, 9>(1.0, 0.6666667, 0.6666667, 0.6666667, 0.25, 0.25, 0.25, 0.25, 0.25);
    let y = sh_basis(normal);
    var sum = 0.0;
    for (var i = 0u; i < 9u; i += 1u) {
        sum += weights[i] * bitcast<f32>(atomicLoad(&integral_terms[9u * leaf + i])) * y[i];
    }
    return max(sum, 0.0);
}

// ---------------------------------------------------------------------------------
// The Gaussian mixture (guiding-core's mixture/): a grid cell and normal side per
// region, a vMF mixture over the sphere sampled and evaluated exactly, learned by
// adding each sample's responsibilities into the region's batch sums; the M-step runs
// on the host between passes.

const LOBE_WORDS: u32 = 8u;

// expm1 and log1p without cancellation near 0 (WGSL has neither).
fn expm1(x: f32) -> f32 {
    if (abs(x) < 1e-2) { return x * (1.0 + x * (0.5 + x * (0.16666667 + x * 0.041666668))); }
    return exp(x) - 1.0;
}

fn log1p(x: f32) -> f32 {
    if (abs(x) < 1e-2) { return x * (1.0 - x * (0.5 - x * (0.33333334 - x * 0.25))); }
    return log(1.0 + x);
}

// GaussianMixture::locate: the grid cell, then the normal's dominant axis and sign.
fn mixture_region(p: vec3<f32>, normal: vec3<f32>) -> u32 {
    if (!all(abs(p) < vec3<f32>(INFINITY))) { return NO_PROBE; }
    let cell = grid_cell(p).index;
    var side = 0u;
    if (params.guide_shape.z == 6u) {
        let a = abs(normal);
        var axis = 2u;
        if (a.x >= a.y && a.x >= a.z) { axis = 0u; } else if (a.y >= a.z) { axis = 1u; }
        side = 2u * axis + select(0u, 1u, normal[axis] < 0.0);
    }
    return cell * params.guide_shape.z + side;
}

fn lobe_word(region: u32, k: u32, i: u32) -> f32 {
    return cdf[(region * params.guide.w + k) * LOBE_WORDS + i];
}

fn lobe_mean(region: u32, k: u32) -> vec3<f32> {
    return vec3<f32>(lobe_word(region, k, 0u), lobe_word(region, k, 1u), lobe_word(region, k, 2u));
}

// VmfLobe::pdf: C(κ)·e^{κ(μ·d − 1)}, with μ·d − 1 = −|d − μ|²/2.
fn lobe_pdf(region: u32, k: u32, d: vec3<f32>) -> f32 {
    let kappa = lobe_word(region, k, 3u);
    if (kappa == 0.0) { return lobe_word(region, k, 4u); }
    let m = d - lobe_mean(region, k);
    return lobe_word(region, k, 4u) * exp(kappa * (-0.5 * dot(m, m)));
}

// MixtureDistribution::sphere_pdf: the mixture with uniform_mix spread over the sphere.
fn mixture_sphere_pdf(region: u32, d: vec3<f32>) -> f32 {
    var sum = 0.0;
    for (var k = 0u; k < params.guide.w; k += 1u) { sum += lobe_word(region, k, 5u) * lobe_pdf(region, k, d); }
    return (1.0 - params.scene.z) * sum + params.scene.z * (0.25 / PI);
}

// MixtureDistribution::pdf: folded onto the normal's hemisphere, as the volume's.
fn mixture_pdf(region: u32, normal: vec3<f32>, d: vec3<f32>) -> f32 {
    if (!(dot(d, normal) >= 0.0)) { return 0.0; }
    return mixture_sphere_pdf(region, d) + mixture_sphere_pdf(region, mirror(d, normal));
}

// VmfLobe::sample (Jakob's w = 1 + ln(u + (1 − u)e^{−2κ})/κ).
fn lobe_sample(region: u32, k: u32, u: vec2<f32>) -> vec3<f32> {
    let kappa = lobe_word(region, k, 3u);
    var w = 1.0 - 2.0 * u.x;
    if (kappa != 0.0) { w = clamp(1.0 + log1p((1.0 - u.x) * expm1(-2.0 * kappa)) / kappa, -1.0, 1.0); }
    let local = spherical_direction(w, 2.0 * PI * u.y);
    return normalize(to_world(frame_from_normal(lobe_mean(region, k)), local));
}

fn mixture_sample(region: u32, normal: vec3<f32>, u: vec2<f32>) -> GuideSample {
    let mix = params.scene.z;
    var d = vec3<f32>(0.0);
    if (u.x < mix) {
        d = spherical_direction(1.0 - 2.0 * (u.x / mix), 2.0 * PI * u.y);
    } else {
        let x = min((u.x - mix) / (1.0 - mix), 0.99999994);
        let lobes = params.guide.w;
        var chosen = lobes - 1u;
        var low = 0.0;
        var cumulative = 0.0;
        for (var k = 0u; k < lobes; k += 1u) {
            let next = cumulative + lobe_word(region, k, 5u);
            if (x < next || k == lobes - 1u) {
                chosen = k;
                low = cumulative;
                break;
            }
            cumulative = next;
        }
        let width = lobe_word(region, chosen, 5u);
        var rest = 0.5;
        if (width > 0.0) { rest = clamp((x - low) / width, 0.0, 0.99999994); }
        d = lobe_sample(region, chosen, vec2<f32>(rest, u.y));
    }
    d = fold_onto_hemisphere(d, normal);
    var s: GuideSample;
    s.wi = d;
    s.pdf = mixture_pdf(region, normal, d);
    return s;
}

// A float added to batch word `index` by compare-exchange, saturating at ±f32::MAX.
fn add_to_batch(index: u32, value: f32) {
    if (value == 0.0) { return; }
    var old = atomicLoad(&q[index]);
    loop {
        let sum = clamp(bitcast<f32>(old) + value, -3.4028235e38, 3.4028235e38);
        let result = atomicCompareExchangeWeak(&q[index], old, bitcast<u32>(sum));
        if (result.exchanged) { break; }
        old = result.old_value;
    }
}

// GaussianMixture::update_sampled: v = target / sampling pdf, split over the lobes by
// their responsibilities into the region's batch sums.
fn mixture_update(region: u32, d: vec3<f32>, goal: f32, pdf: f32) {
    if (!(abs(dot(d, d) - 1.0) < 1e-3 && pdf > 0.0 && pdf < INFINITY)) { return; }
    let weight = min(goal / pdf, 1e30);
    let lobes = params.guide.w;
    let stride = 1u + 4u * lobes;
    let base = region * stride;
    var total = 0.0;
    for (var k = 0u; k < lobes; k += 1u) { total += lobe_word(region, k, 5u) * lobe_pdf(region, k, d); }
    let fallback = u32(lobe_word(region, 0u, 7u));
    // The count saturates, as guiding-core's increment does.
    var count = atomicLoad(&q[base]);
    loop {
        if (count == 0xffffffffu) { break; }
        let result = atomicCompareExchangeWeak(&q[base], count, count + 1u);
        if (result.exchanged) { break; }
        count = result.old_value;
    }
    for (var k = 0u; k < lobes; k += 1u) {
        var r = select(0.0, 1.0, k == fallback);
        if (total > 0.0 && total < INFINITY) { r = lobe_word(region, k, 5u) * lobe_pdf(region, k, d) / total; }
        let share = r * weight;
        let word = base + 1u + 4u * k;
        add_to_batch(word, share);
        add_to_batch(word + 1u, share * d.x);
        add_to_batch(word + 2u, share * d.y);
        add_to_batch(word + 3u, share * d.z);
    }
}

// GaussianMixture::estimate_integral: S·Σ_k w_k·fs(ω_k)·cos θ_k with ω_k drawn from
// lobe k by the same `u`.
fn mixture_integral(region: u32, m: Material, shading: Shading, wo_local: vec3<f32>, u: vec2<f32>) -> f32 {
    let scale = lobe_word(region, 0u, 6u);
    if (!(scale > 0.0)) { return 0.0; }
    var sum = 0.0;
    for (var k = 0u; k < params.guide.w; k += 1u) {
        let wi = lobe_sample(region, k, u);
        sum += lobe_word(region, k, 5u) * luminance(bsdf_eval(m, wo_local, to_local(shading.frame, wi)));
    }
    return min(scale * sum, 3.4e38);
}

// ---------------------------------------------------------------------------------
// Either guide, by params.volume_grid.w: a region is a probe, a leaf or a mixture
// region.

fn guide_locate(point: vec3<f32>, normal: vec3<f32>) -> u32 {
    if (params.volume_grid.w == GUIDE_VOLUME) { return volume_leaf(point); }
    if (params.volume_grid.w == GUIDE_MIXTURE) { return mixture_region(point, normal); }
    return locate(point, normal);
}

// pdf per steradian of world direction `wi` at `region`, on the side of `normal`.
fn guide_pdf(region: u32, normal: vec3<f32>, wi: vec3<f32>) -> f32 {
    if (params.volume_grid.w == GUIDE_VOLUME) { return volume_pdf(region, normal, wi); }
    if (params.volume_grid.w == GUIDE_MIXTURE) { return mixture_pdf(region, normal, wi); }
    return grid_pdf(region, wi);
}

fn guide_sample(region: u32, normal: vec3<f32>, u: vec2<f32>) -> GuideSample {
    if (params.volume_grid.w == GUIDE_VOLUME) { return volume_sample(region, normal, u); }
    if (params.volume_grid.w == GUIDE_MIXTURE) { return mixture_sample(region, normal, u); }
    return grid_sample(region, u);
}

// The patch of `region` holding world direction `wi`, or N (none).
fn guide_patch(region: u32, wi: vec3<f32>) -> u32 {
    if (params.volume_grid.w == GUIDE_VOLUME) { return sphere_patch_of(wi); }
    return patch_of(to_local(frame_from_normal(probe_normal(region)), wi));
}

// A float added to a probe's Lambertian sum by compare-exchange (storage pointers
// cannot be passed to functions in WGSL, so this names its array).
fn add_to_lambertian_sum(probe: u32, value: f32) {
    var old = atomicLoad(&integral_terms[probe]);
    loop {
        let result = atomicCompareExchangeWeak(&integral_terms[probe], old, bitcast<u32>(bitcast<f32>(old) + value));
        if (result.exchanged) { break; }
        old = result.old_value;
    }
}

// Eq. (1) with the guide's rule: Q' = (1 − α)Q + α·target, above the floor; the
// mixture's batch sums instead (which need the direction's sampling pdf).
fn guide_update(region: u32, wi: vec3<f32>, goal: f32, pdf: f32) {
    if (!(goal >= 0.0 && goal < INFINITY)) { return; }
    if (params.volume_grid.w == GUIDE_MIXTURE) {
        mixture_update(region, wi, goal, pdf);
        return;
    }
    let entry = guide_patch(region, wi);
    if (entry >= params.guide.w) { return; }
    let index = region * params.guide.w + entry;
    let entry_visits = atomicAdd(&patch_visits[index], 1u);
    let visits = atomicAdd(&region_visits[region], 1u);
    // guide_rule.z: 0 exponential (α = w), 1 simple average, 2 region visits.
    var alpha = params.guide_rule.w;
    if (params.guide_rule.z == 1.0) { alpha = 1.0 / (1.0 + f32(entry_visits)); }
    if (params.guide_rule.z == 2.0) { alpha = 1.0 / (1.0 + f32(visits)); }
    var old = atomicLoad(&q[index]);
    var stored = 0.0;
    loop {
        let value = bitcast<f32>(old);
        var mixed = (1.0 - alpha) * value + alpha * goal;
        if (alpha <= 0.0) { mixed = value; }
        if (alpha >= 1.0) { mixed = goal; }
        stored = max(min(mixed, 3.4e38), params.guide_rule.x);
        let result = atomicCompareExchangeWeak(&q[index], old, bitcast<u32>(stored));
        if (result.exchanged) { break; }
        old = result.old_value;
    }
    // The grid keeps its Lambertian sums current; the volume projects at each rebuild.
    if (params.volume_grid.w == GUIDE_HEMISPHERE) {
        let change = (stored - bitcast<f32>(old)) * patch_weights[entry];
        if (change != 0.0) { add_to_lambertian_sum(region, change); }
    }
}

// ∫ Q fs cos at `region` for the material: exact (grid) or from the spherical harmonics
// (volume) for diffuse surfaces, one BSDF sample for glossy ones
// (IntegralEstimator::BsdfSampled).
fn guide_integral(region: u32, m: Material, shading: Shading, wo_local: vec3<f32>, u: vec2<f32>, u_lobe: f32) -> f32 {
    if (params.volume_grid.w == GUIDE_MIXTURE) { return mixture_integral(region, m, shading, wo_local, u); }
    if (m.kind == DIFFUSE) {
        if (params.volume_grid.w == GUIDE_VOLUME) {
            return luminance(m.albedo.xyz) * sh_cosine_integral(region, shading.frame.normal);
        }
        return luminance(m.albedo.xyz) / PI * max(bitcast<f32>(atomicLoad(&integral_terms[region])), 0.0);
    }
    let s = bsdf_sample(m, wo_local, u, u_lobe);
    if (!s.ok) { return 0.0; }
    let entry = guide_patch(region, to_world(shading.frame, s.wi));
    if (entry >= params.guide.w) { return 0.0; }
    return bitcast<f32>(atomicLoad(&q[region * params.guide.w + entry])) * luminance(s.weight);
}

// Draws arrayLength(guide_samples) directions from probe `params.pass_index`'s
// distribution: w holds the GPU's pdf (tests check the sampler against guiding-core).
@compute @workgroup_size(64, 1, 1)
fn sample_guide(@builtin(global_invocation_id) id: vec3<u32>) {
    if (id.x >= arrayLength(&guide_samples)) { return; }
    rng_state = pcg_hash(id.x ^ pcg_hash(params.seed));
    let s = guide_sample(params.pass_index, params.sample_normal.xyz, next_vec2());
    guide_samples[id.x] = vec4<f32>(s.wi, s.pdf);
}

// Rebuilds the CDF of every region whose visits moved since its last build (one
// invocation per region): p_k = (1 − mix)·Q_k/ΣQ + mix/N, quantised to 2⁻²⁴ like
// guiding-core's build_cdf, with the grid's exact Lambertian sum or the volume's
// spherical-harmonic projection.
@compute @workgroup_size(64, 1, 1)
fn rebuild(@builtin(global_invocation_id) id: vec3<u32>) {
    let region = id.x;
    if (region >= params.guide.z) { return; }
    let visits = atomicLoad(&region_visits[region]);
    if (visits == built_visits[region] && params.pass_index != 0xffffffffu) { return; }
    built_visits[region] = visits;
    let n = params.guide.w;
    let base = region * n;
    let volume = params.volume_grid.w == GUIDE_VOLUME;
    var total = 0.0;
    var cosine_sum = 0.0;
    var sh = array<f32, 9>(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    for (var k = 0u; k < n; k += 1u) {
        let value = bitcast<f32>(atomicLoad(&q[base + k]));
        total += value;
        if (volume) {
            for (var i = 0u; i < 9u; i += 1u) { sh[i] += value * patch_weights[9u * k + i]; }
        } else {
            cosine_sum += value * patch_weights[k];
        }
    }
    if (volume) {
        for (var i = 0u; i < 9u; i += 1u) {
            atomicStore(&integral_terms[9u * region + i], bitcast<u32>(clamp(sh[i], -3.4e38, 3.4e38)));
        }
    } else {
        atomicStore(&integral_terms[region], bitcast<u32>(cosine_sum));
    }
    var mix = params.scene.z;
    if (!(total > 0.0)) { mix = 1.0; }
    let scale = select(0.0, (1.0 - mix) / total * 16777216.0, total > 0.0);
    let uniform = mix / f32(n) * 16777216.0;
    var cumulative = 0.0;
    for (var k = 0u; k < n; k += 1u) {
        cumulative += bitcast<f32>(atomicLoad(&q[base + k])) * scale + uniform;
        cdf[base + k] = min(floor(cumulative + 0.5), 16777216.0) / 16777216.0;
    }
    cdf[base + n - 1u] = 1.0;
}

// ---------------------------------------------------------------------------------
// The path (integrator.rs's PathTracer::radiance).

// What a vertex knows about the radiance along its sampled direction (integrator.rs's
// Onward): 0 the guide's integral at the next vertex, 1 carry the next goal scaled by
// the next vertex's throughput factor, 2 the path ended there.
const ONWARD_INTEGRAL: u32 = 0u;
const ONWARD_CARRY: u32 = 1u;
const ONWARD_END: u32 = 2u;

struct LearningVertex {
    probe: u32,
    onward_kind: u32,
    onward: f32,
    arriving: f32,
    direction: vec3<f32>,
    pdf: f32,
};

var<private> path: array<LearningVertex, MAX_VERTICES>;

fn add_arriving(count: u32, value: f32) {
    if (count > 0u) { path[count - 1u].arriving += value; }
}

@compute @workgroup_size(8, 8, 1)
fn trace(@builtin(global_invocation_id) id: vec3<u32>) {
    if (id.x >= params.width || id.y >= params.height) { return; }
    let pixel = id.y * params.width + id.x;
    rng_state = pcg_hash(pixel ^ pcg_hash(params.pass_index ^ pcg_hash(params.seed)));

    // Camera ray through a jittered point of the pixel (camera.rs).
    let jitter = next_vec2();
    let width = f32(params.width);
    let height = f32(params.height);
    let aspect = width / height;
    let tan_half = params.forward.w;
    let ndc_x = (2.0 * (f32(id.x) + jitter.x) / width - 1.0) * aspect * tan_half;
    let ndc_y = (1.0 - 2.0 * (f32(id.y) + jitter.y) / height) * tan_half;
    var origin = params.eye.xyz;
    var direction = normalize(params.forward.xyz + params.right.xyz * ndc_x + params.up.xyz * ndc_y);

    let uses_nee = params.method == METHOD_NEE || params.method == METHOD_GUIDED_NEE;
    let guided = (params.method == METHOD_GUIDED || params.method == METHOD_GUIDED_NEE) && params.guide.x != 0u;
    let learning = guided && params.guide.y != 0u;
    let p_guide = params.scene.y;
    var radiance = vec3<f32>(0.0);
    var throughput = vec3<f32>(1.0);
    var previous_point = vec3<f32>(0.0);
    var previous_pdf = 0.0;
    var previous_delta = true;
    var rays = 0u;
    var vertices = 0u;
    var count = 0u;
    for (var depth = 0u; depth < params.max_depth; depth += 1u) {
        rays += 1u;
        let hit = intersect(origin, direction, 0.0, INFINITY);
        if (hit.primitive == NO_LIGHT) {
            if (params.environment.w > 0.0) {
                // A constant environment's pdf is uniform over the sphere.
                var weight = 1.0;
                if (uses_nee && !previous_delta && depth > 0u) {
                    weight = power_heuristic(previous_pdf, params.environment.w / (4.0 * PI));
                }
                radiance += throughput * params.environment.xyz * weight;
                add_arriving(count, weight * luminance(params.environment.xyz));
            }
            break;
        }
        vertices += 1u;
        let info = triangle_info[hit.primitive];
        let m = materials[bitcast<u32>(info.w)];
        let geometric_normal = info.xyz;
        let point = origin + direction * hit.t;
        let wo = -direction;
        if (m.emission.x + m.emission.y + m.emission.z > 0.0 && dot(geometric_normal, wo) > 0.0) {
            var weight = 1.0;
            let light = light_of_triangle[hit.primitive];
            if (uses_nee && !previous_delta && depth > 0u && light != NO_LIGHT) {
                weight = power_heuristic(previous_pdf, light_pdf(light, previous_point, point, geometric_normal));
            }
            radiance += throughput * m.emission.xyz * weight;
            add_arriving(count, weight * luminance(m.emission.xyz));
        }
        let shading = shading_frame(m, geometric_normal, wo);
        let delta = is_delta(m);
        let wo_local = to_local(shading.frame, wo);
        var probe = NO_PROBE;
        if (guided && !delta) { probe = guide_locate(point, shading.frame.normal); }
        if (learning && !delta && probe != NO_PROBE && count > 0u) {
            let u = next_vec2();
            let u_lobe = next_f32();
            path[count - 1u].onward_kind = ONWARD_INTEGRAL;
            path[count - 1u].onward = guide_integral(probe, m, shading, wo_local, u, u_lobe);
        }
        if (depth + 1u >= params.max_depth) { break; }
        let p = select(0.0, p_guide, probe != NO_PROBE);

        // Next-event estimation: the environment or one area light.
        if (uses_nee && !delta) {
            let u_choice = next_f32();
            let u_select = next_f32();
            let u = next_vec2();
            var wi = vec3<f32>(0.0);
            var emitted = vec3<f32>(0.0);
            var pdf = 0.0;
            var distance = INFINITY;
            if (u_choice < params.environment.w) {
                let z = 1.0 - 2.0 * u.x;
                let r = sqrt(max(1.0 - z * z, 0.0));
                wi = vec3<f32>(r * cos(2.0 * PI * u.y), r * sin(2.0 * PI * u.y), z);
                emitted = params.environment.xyz;
                pdf = params.environment.w / (4.0 * PI);
            } else if (params.light_count > 0u) {
                let light = sample_light_cdf(u_select);
                let l = lights[light];
                let su = sqrt(u.x);
                let b1 = su * (1.0 - u.y);
                let b2 = su * u.y;
                let goal = l.v0.xyz * (1.0 - b1 - b2) + l.v1.xyz * b1 + l.v2.xyz * b2;
                let light_normal = normalize(cross(l.v1.xyz - l.v0.xyz, l.v2.xyz - l.v0.xyz));
                let to_light = goal - point;
                let distance2 = dot(to_light, to_light);
                distance = sqrt(distance2);
                wi = to_light / distance;
                let cos_light = -dot(light_normal, wi);
                if (cos_light > 0.0 && distance > 0.0) {
                    emitted = l.emission.xyz;
                    pdf = (1.0 - params.environment.w) * l.emission.w * distance2 / (cos_light * l.v2.w);
                }
            }
            let wi_local = to_local(shading.frame, wi);
            let f = bsdf_eval(m, wo_local, wi_local);
            let above = dot(wi, shading.geometric) > 0.0;
            if (pdf > 0.0 && pdf < INFINITY && above && (f.x + f.y + f.z) > 0.0 && (emitted.x + emitted.y + emitted.z) > 0.0) {
                let start = spawn(point, geometric_normal, wi);
                var t_max = INFINITY;
                if (distance < INFINITY) {
                    let goal = point + wi * distance;
                    let margin = epsilon_at(point) + epsilon_at(goal);
                    t_max = max(distance - margin, 0.0) * (1.0 - 1e-5);
                }
                rays += 1u;
                if (!occluded(start, wi, t_max)) {
                    var scatter = bsdf_pdf(m, wo_local, wi_local);
                    if (p > 0.0) { scatter = p * guide_pdf(probe, shading.frame.normal, wi) + (1.0 - p) * scatter; }
                    let direct = f * emitted * (power_heuristic(pdf, scatter) / pdf);
                    radiance += throughput * direct;
                    add_arriving(count, luminance(direct));
                }
            }
        }

        // Russian roulette before the direction is drawn, as on the CPU: a survival that
        // depended on the direction would bias what the guide learns.
        var survival = 1.0;
        if (depth + 1u >= params.rr_depth) {
            survival = min(max(max(throughput.x, throughput.y), throughput.z), 0.95);
            if (survival <= 0.0 || next_f32() >= survival) { break; }
            throughput /= survival;
        }

        // The next direction: the guide with probability p where a probe exists, else
        // the BSDF, weighted by the one-sample mixture pdf.
        let u_choice = next_f32();
        let u_lobe = next_f32();
        let u = next_vec2();
        var wi = vec3<f32>(0.0);
        var factor = vec3<f32>(0.0);
        var pdf = 0.0;
        if (delta) {
            let s = bsdf_sample(m, wo_local, u, u_lobe);
            if (!s.ok) { break; }
            wi = to_world(shading.frame, s.wi);
            factor = s.weight;
            pdf = s.pdf;
        } else {
            var f = vec3<f32>(0.0);
            if (u_choice < p) {
                let g = guide_sample(probe, shading.frame.normal, u);
                wi = g.wi;
                f = bsdf_eval(m, wo_local, to_local(shading.frame, wi));
            } else {
                let s = bsdf_sample(m, wo_local, u, u_lobe);
                if (!s.ok) { break; }
                wi = to_world(shading.frame, s.wi);
                f = s.weight * s.pdf;
            }
            if (dot(wi, shading.geometric) <= 0.0) { break; }
            pdf = bsdf_pdf(m, wo_local, to_local(shading.frame, wi));
            if (p > 0.0) { pdf = p * guide_pdf(probe, shading.frame.normal, wi) + (1.0 - p) * pdf; }
            if (!(pdf > 0.0 && pdf < INFINITY) || (f.x + f.y + f.z) <= 0.0) { break; }
            factor = f / pdf;
        }
        if (!(factor.x < INFINITY && factor.y < INFINITY && factor.z < INFINITY)) { break; }
        throughput *= factor;
        if (learning && count < MAX_VERTICES) {
            // A vertex without an estimate of its own passes its goal back, scaled by its
            // factor and 1/survival.
            if ((delta || probe == NO_PROBE) && count > 0u) {
                path[count - 1u].onward_kind = ONWARD_CARRY;
                path[count - 1u].onward = luminance(factor) / survival;
            }
            path[count].probe = probe;
            path[count].onward_kind = ONWARD_END;
            path[count].onward = 0.0;
            path[count].arriving = 0.0;
            path[count].direction = wi;
            path[count].pdf = pdf;
            count += 1u;
        }
        previous_point = point;
        previous_pdf = pdf;
        previous_delta = delta;
        origin = spawn(point, geometric_normal, wi);
        direction = wi;
    }
    // Eq. (1) along the finished path, last vertex first.
    var next_target = 0.0;
    for (var i = i32(count) - 1; i >= 0; i -= 1) {
        let v = path[i];
        var onward = 0.0;
        if (v.onward_kind == ONWARD_INTEGRAL) { onward = v.onward; }
        if (v.onward_kind == ONWARD_CARRY) { onward = v.onward * next_target; }
        let goal = v.arriving + onward;
        if (v.probe != NO_PROBE) { guide_update(v.probe, v.direction, goal, v.pdf); }
        next_target = goal;
    }
    pass_image[pixel] = vec4<f32>(radiance, 1.0);
    atomicAdd(&counters.paths, 1u);
    if (max(max(radiance.x, radiance.y), radiance.z) > 0.0) { atomicAdd(&counters.nonzero, 1u); }
    atomicAdd(&counters.rays, rays);
    atomicAdd(&counters.vertices, vertices);
}

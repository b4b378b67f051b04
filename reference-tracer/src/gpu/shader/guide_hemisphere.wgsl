// ---------------------------------------------------------------------------------
// The hemisphere grid (guiding-core's hemisphere/): lookup, sampling, pdf, Eq. (1).

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
    let c = (p - params.lookup_origin) / params.lookup_cell_size;
    return clamp(vec3<i32>(floor_i32(c.x), floor_i32(c.y), floor_i32(c.z)), vec3<i32>(-MAX_CELL), vec3<i32>(MAX_CELL));
}

fn bucket(cell: vec3<i32>) -> u32 {
    let hash = (u32(cell.x) * 73856093u) ^ (u32(cell.y) * 19349663u) ^ (u32(cell.z) * 83492791u);
    return hash & (params.lookup_buckets - 1u);
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
        if ((result.probe == NO_PROBE || d2 < result.distance2) && dot(probe_normal(p), normal) >= params.max_normal_cos) {
            result.probe = p;
            result.distance2 = d2;
        }
    }
    return result;
}

// ProbeLookup::nearest: the nearest probe whose normal is within the largest angle of
// `normal`, within the search rings; NO_PROBE otherwise.
fn hemisphere_locate(query: vec3<f32>, normal: vec3<f32>) -> u32 {
    var best: Nearest;
    best.probe = NO_PROBE;
    best.distance2 = INFINITY;
    let cell_size = params.lookup_cell_size;
    let scaled = (query - params.lookup_origin) / cell_size;
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
    for (var ring = 1; ring <= i32(params.search_rings); ring += 1) {
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
    return 2.0 * PI / f32(params.guide_patches);
}

// PatchLayout::patch_of for the cylindrical mapping; N (none) below the horizon.
fn patch_of(local: vec3<f32>) -> u32 {
    if (!(local.z >= 0.0)) { return params.guide_patches; }
    var phi = atan2(local.y, local.x);
    if (phi < 0.0) { phi += 2.0 * PI; }
    let rows = params.patch_rows;
    let columns = params.patch_columns;
    let iu = min(u32(clamp(local.z, 0.0, 1.0) * f32(rows)), rows - 1u);
    let iv = min(u32(phi * (0.5 / PI) * f32(columns)), columns - 1u);
    return iu * columns + iv;
}

fn direction_in_patch(entry: u32, xi: vec2<f32>) -> vec3<f32> {
    let rows = params.patch_rows;
    let columns = params.patch_columns;
    let uv = vec2<f32>((f32(entry / columns) + xi.x) / f32(rows), (f32(entry % columns) + xi.y) / f32(columns));
    let d = spherical_direction(clamp(uv.x, 0.0, 1.0), 2.0 * PI * uv.y);
    if (d.z >= MIN_SAMPLED_COS) { return d; }
    let planar = sqrt(d.x * d.x + d.y * d.y);
    let scale = sqrt(1.0 - MIN_SAMPLED_COS * MIN_SAMPLED_COS) / planar;
    return vec3<f32>(d.x * scale, d.y * scale, MIN_SAMPLED_COS);
}

// The patch of probe `region` holding world direction `wi`, or N (none).
fn hemisphere_patch(region: u32, wi: vec3<f32>) -> u32 {
    return patch_of(to_local(frame_from_normal(probe_normal(region)), wi));
}

fn hemisphere_pdf(region: u32, normal: vec3<f32>, wi: vec3<f32>) -> f32 {
    let entry = hemisphere_patch(region, wi);
    if (entry >= params.guide_patches) { return 0.0; }
    return patch_probability(region, entry) / patch_solid_angle();
}

fn hemisphere_sample(region: u32, normal: vec3<f32>, u: vec2<f32>) -> GuideSample {
    let c = invert_cdf(region, u.x);
    var s: GuideSample;
    s.wi = to_world(frame_from_normal(probe_normal(region)), direction_in_patch(c.entry, vec2<f32>(c.rest, u.y)));
    s.pdf = patch_probability(region, c.entry) / patch_solid_angle();
    return s;
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

// The learning hooks of the guide dispatch (guide.wgsl); hemisphere_locate, _pdf and
// _sample are above.

// Eq. (1), the probe's Lambertian sum kept current.
fn hemisphere_learn(region: u32, normal: vec3<f32>, wi: vec3<f32>, goal: f32, pdf: f32) {
    let entry = hemisphere_patch(region, wi);
    let change = table_learn(region, entry, goal);
    if (change != 0.0) {
        let weighted = change * patch_weights[entry];
        if (weighted != 0.0) { add_to_lambertian_sum(region, weighted); }
    }
}

// ∫ Q fs cos: exact from the Lambertian sum for diffuse surfaces, one BSDF sample for
// glossy ones.
fn hemisphere_integral(region: u32, m: Material, shading: Shading, wo_local: vec3<f32>, u: vec2<f32>, u_lobe: f32) -> f32 {
    if (m.kind == DIFFUSE) {
        return luminance(m.albedo.xyz) / PI * max(bitcast<f32>(atomicLoad(&integral_terms[region])), 0.0);
    }
    let d = bsdf_direction(m, shading, wo_local, u, u_lobe);
    if (!d.ok) { return 0.0; }
    return table_value(region, hemisphere_patch(region, d.wi)) * d.weight;
}

// The probe's exact Lambertian sum Σ Q_k·∫_k cos, then its CDF.
fn hemisphere_rebuild(region: u32) {
    let n = params.guide_patches;
    let base = region * n;
    var cosine_sum = 0.0;
    for (var k = 0u; k < n; k += 1u) { cosine_sum += bitcast<f32>(atomicLoad(&q[base + k])) * patch_weights[k]; }
    atomicStore(&integral_terms[region], bitcast<u32>(cosine_sum));
    table_rebuild_cdf(region);
}

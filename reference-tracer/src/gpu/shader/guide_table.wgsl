// ---------------------------------------------------------------------------------
// What the guide structures share (guiding-core's q_table.rs and its CDFs): the sample
// type, a region's CDF and its inversion, the cell grid of the volume and the mixture,
// and the tables of Q per patch that the grid and the volume learn and sample alike.
// Each structure's own file then defines its hooks (PREFIX_locate, _pdf, _sample,
// _learn, _integral, _rebuild), which the generated dispatch (guide_locate, …) calls by
// params.guide_kind.

const NO_PROBE: u32 = 0xffffffffu;

fn patch_probability(region: u32, entry: u32) -> f32 {
    let base = region * params.guide_patches;
    let low = select(0.0, cdf[base + entry - 1u], entry > 0u);
    return cdf[base + entry] - low;
}

struct CdfSample {
    entry: u32,
    rest: f32,
};

// sample_cdf over region `region`'s patches: the patch, and `u` rescaled inside it.
fn invert_cdf(region: u32, u: f32) -> CdfSample {
    let n = params.guide_patches;
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

// CellGrid (the volume's and the mixture's): `p` in cell units from the low corner, the
// cell holding it (the nearest one outside) and that cell's index.
struct GridCell {
    scaled: vec3<f32>,
    cell: vec3<i32>,
    index: u32,
}

fn grid_cell(p: vec3<f32>) -> GridCell {
    let resolution = vec3<i32>(params.grid_cells);
    var g: GridCell;
    g.scaled = max((p - params.grid_low) * params.grid_cells_per_unit, vec3<f32>(0.0));
    g.cell = min(vec3<i32>(g.scaled), resolution - vec3<i32>(1));
    g.index = u32((g.cell.z * resolution.y + g.cell.y) * resolution.x + g.cell.x);
    return g;
}

// Eq. (1) on entry `entry` of `region`'s table with the guide's rule:
// Q' = (1 − α)Q + α·target, above the floor. Returns Q' − Q (0 where nothing changed,
// or where the entry is none).
fn table_learn(region: u32, entry: u32, goal: f32) -> f32 {
    if (entry >= params.guide_patches) { return 0.0; }
    let index = region * params.guide_patches + entry;
    let entry_visits = atomicAdd(&patch_visits[index], 1u);
    let visits = atomicAdd(&region_visits[region], 1u);
    // α: constant, 1/(1 + the entry's visits) or 1/(1 + the region's visits).
    var alpha = params.learning_rate_alpha;
    if (params.learning_rate == LEARNING_RATE_ENTRY_VISITS) { alpha = 1.0 / (1.0 + f32(entry_visits)); }
    if (params.learning_rate == LEARNING_RATE_REGION_VISITS) { alpha = 1.0 / (1.0 + f32(visits)); }
    var old = atomicLoad(&q[index]);
    var stored = 0.0;
    loop {
        let value = bitcast<f32>(old);
        var mixed = (1.0 - alpha) * value + alpha * goal;
        if (alpha <= 0.0) { mixed = value; }
        if (alpha >= 1.0) { mixed = goal; }
        stored = max(min(mixed, 3.4e38), params.q_floor);
        let result = atomicCompareExchangeWeak(&q[index], old, bitcast<u32>(stored));
        if (result.exchanged) { break; }
        old = result.old_value;
    }
    return stored - bitcast<f32>(old);
}

// Q of entry `entry` of `region`'s table (0 for none).
fn table_value(region: u32, entry: u32) -> f32 {
    if (entry >= params.guide_patches) { return 0.0; }
    return bitcast<f32>(atomicLoad(&q[region * params.guide_patches + entry]));
}

// One direction drawn from the material (world space) and its weight fs·cos/pdf
// (luminance), for the integral of Eq. (1) at glossy surfaces
// (IntegralEstimator::BsdfSampled); `ok` false where it drew none.
struct BsdfDirection {
    wi: vec3<f32>,
    weight: f32,
    ok: bool,
};

fn bsdf_direction(m: Material, shading: Shading, wo_local: vec3<f32>, u: vec2<f32>, u_lobe: f32) -> BsdfDirection {
    let s = bsdf_sample(m, wo_local, u, u_lobe);
    var d: BsdfDirection;
    d.ok = s.ok;
    if (s.ok) {
        d.wi = to_world(shading.frame, s.wi);
        d.weight = luminance(s.weight);
    }
    return d;
}

// The CDF of `region`'s table: p_k = (1 − mix)·Q_k/ΣQ + mix/N, quantised to 2⁻²⁴ like
// guiding-core's build_cdf.
fn table_rebuild_cdf(region: u32) {
    let n = params.guide_patches;
    let base = region * n;
    var total = 0.0;
    for (var k = 0u; k < n; k += 1u) { total += bitcast<f32>(atomicLoad(&q[base + k])); }
    var mix = params.uniform_mix;
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

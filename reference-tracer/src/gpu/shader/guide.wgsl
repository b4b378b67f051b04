// ---------------------------------------------------------------------------------
// Either guide, by params.guide_kind: a region is a probe, a leaf or a mixture
// region.

fn guide_locate(point: vec3<f32>, normal: vec3<f32>) -> u32 {
    if (params.guide_kind == GUIDE_VOLUME) { return volume_leaf(point); }
    if (params.guide_kind == GUIDE_MIXTURE) { return mixture_region(point, normal); }
    return locate(point, normal);
}

// pdf per steradian of world direction `wi` at `region`, on the side of `normal`.
fn guide_pdf(region: u32, normal: vec3<f32>, wi: vec3<f32>) -> f32 {
    if (params.guide_kind == GUIDE_VOLUME) { return volume_pdf(region, normal, wi); }
    if (params.guide_kind == GUIDE_MIXTURE) { return mixture_pdf(region, normal, wi); }
    return grid_pdf(region, wi);
}

fn guide_sample(region: u32, normal: vec3<f32>, u: vec2<f32>) -> GuideSample {
    if (params.guide_kind == GUIDE_VOLUME) { return volume_sample(region, normal, u); }
    if (params.guide_kind == GUIDE_MIXTURE) { return mixture_sample(region, normal, u); }
    return grid_sample(region, u);
}

// The patch of `region` holding world direction `wi`, or N (none).
fn guide_patch(region: u32, wi: vec3<f32>) -> u32 {
    if (params.guide_kind == GUIDE_VOLUME) { return sphere_patch_of(wi); }
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
    if (params.guide_kind == GUIDE_MIXTURE) {
        mixture_update(region, wi, goal, pdf);
        return;
    }
    let entry = guide_patch(region, wi);
    if (entry >= params.guide_patches) { return; }
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
    // The grid keeps its Lambertian sums current; the volume projects at each rebuild.
    if (params.guide_kind == GUIDE_HEMISPHERE) {
        let change = (stored - bitcast<f32>(old)) * patch_weights[entry];
        if (change != 0.0) { add_to_lambertian_sum(region, change); }
    }
}

// ∫ Q fs cos at `region` for the material: exact (grid) or from the spherical harmonics
// (volume) for diffuse surfaces, one BSDF sample for glossy ones
// (IntegralEstimator::BsdfSampled).
fn guide_integral(region: u32, m: Material, shading: Shading, wo_local: vec3<f32>, u: vec2<f32>, u_lobe: f32) -> f32 {
    if (params.guide_kind == GUIDE_MIXTURE) { return mixture_integral(region, m, shading, wo_local, u); }
    if (m.kind == DIFFUSE) {
        if (params.guide_kind == GUIDE_VOLUME) {
            return luminance(m.albedo.xyz) * sh_cosine_integral(region, shading.frame.normal);
        }
        return luminance(m.albedo.xyz) / PI * max(bitcast<f32>(atomicLoad(&integral_terms[region])), 0.0);
    }
    let s = bsdf_sample(m, wo_local, u, u_lobe);
    if (!s.ok) { return 0.0; }
    let entry = guide_patch(region, to_world(shading.frame, s.wi));
    if (entry >= params.guide_patches) { return 0.0; }
    return bitcast<f32>(atomicLoad(&q[region * params.guide_patches + entry])) * luminance(s.weight);
}

// Draws arrayLength(guide_samples) directions from probe `params.pass_index`'s
// distribution: w holds the GPU's pdf (tests check the sampler against guiding-core).
@compute @workgroup_size(64, 1, 1)
fn sample_guide(@builtin(global_invocation_id) id: vec3<u32>) {
    if (id.x >= arrayLength(&guide_samples)) { return; }
    rng_state = pcg_hash(id.x ^ pcg_hash(params.seed));
    let s = guide_sample(params.pass_index, params.sample_normal, next_vec2());
    guide_samples[id.x] = vec4<f32>(s.wi, s.pdf);
}

// Rebuilds the CDF of every region whose visits moved since its last build (one
// invocation per region): p_k = (1 − mix)·Q_k/ΣQ + mix/N, quantised to 2⁻²⁴ like
// guiding-core's build_cdf, with the grid's exact Lambertian sum or the volume's
// spherical-harmonic projection.
@compute @workgroup_size(64, 1, 1)
fn rebuild(@builtin(global_invocation_id) id: vec3<u32>) {
    let region = id.x;
    if (region >= params.guide_regions) { return; }
    let visits = atomicLoad(&region_visits[region]);
    if (visits == built_visits[region] && params.pass_index != 0xffffffffu) { return; }
    built_visits[region] = visits;
    let n = params.guide_patches;
    let base = region * n;
    let volume = params.guide_kind == GUIDE_VOLUME;
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

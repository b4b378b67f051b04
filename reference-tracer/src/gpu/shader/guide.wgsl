// ---------------------------------------------------------------------------------
// The guide, whichever structure params.guide_kind names: guide_locate, guide_pdf,
// guide_sample, guide_learn, guide_integral and guide_rebuild are generated before this
// file (gpu/shader.rs), each calling the structure's own hook.

// Eq. (1) with the guide's rule: Q' = (1 − α)Q + α·target (the mixture's batch sums
// instead, which need the direction's sampling pdf), for a finite target ≥ 0.
fn guide_update(region: u32, normal: vec3<f32>, wi: vec3<f32>, goal: f32, pdf: f32) {
    if (!(goal >= 0.0 && goal < INFINITY)) { return; }
    guide_learn(region, normal, wi, goal, pdf);
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

// Rebuilds every region whose visits moved since its last build (one invocation per
// region): its CDF and what its integral estimate reads (the grid's exact Lambertian
// sum, the volume's spherical-harmonic projection).
@compute @workgroup_size(64, 1, 1)
fn rebuild(@builtin(global_invocation_id) id: vec3<u32>) {
    let region = id.x;
    if (region >= params.guide_regions) { return; }
    let visits = atomicLoad(&region_visits[region]);
    if (visits == built_visits[region] && params.pass_index != 0xffffffffu) { return; }
    built_visits[region] = visits;
    guide_rebuild(region);
}

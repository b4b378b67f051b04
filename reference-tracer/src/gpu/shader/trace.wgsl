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
    // The surface normal the probe was located with.
    normal: vec3<f32>,
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
    let tan_half = params.tan_half_fov_y;
    let ndc_x = (2.0 * (f32(id.x) + jitter.x) / width - 1.0) * aspect * tan_half;
    let ndc_y = (1.0 - 2.0 * (f32(id.y) + jitter.y) / height) * tan_half;
    var origin = params.eye;
    var direction = normalize(params.forward + params.right * ndc_x + params.up * ndc_y);

    let uses_nee = params.method == METHOD_NEE || params.method == METHOD_GUIDED_NEE;
    let guided = (params.method == METHOD_GUIDED || params.method == METHOD_GUIDED_NEE) && params.guide_present != 0u;
    let learning = guided && params.guide_learns != 0u;
    let p_guide = params.guide_probability;
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
            if (params.environment_choice > 0.0) {
                // A constant environment's pdf is uniform over the sphere.
                var weight = 1.0;
                if (uses_nee && !previous_delta && depth > 0u) {
                    weight = power_heuristic(previous_pdf, params.environment_choice / (4.0 * PI));
                }
                radiance += throughput * params.environment_radiance * weight;
                add_arriving(count, weight * luminance(params.environment_radiance));
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
            if (u_choice < params.environment_choice) {
                let z = 1.0 - 2.0 * u.x;
                let r = sqrt(max(1.0 - z * z, 0.0));
                wi = vec3<f32>(r * cos(2.0 * PI * u.y), r * sin(2.0 * PI * u.y), z);
                emitted = params.environment_radiance;
                pdf = params.environment_choice / (4.0 * PI);
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
                    pdf = (1.0 - params.environment_choice) * l.emission.w * distance2 / (cos_light * l.v2.w);
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
            path[count].normal = shading.frame.normal;
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
        if (v.probe != NO_PROBE) { guide_update(v.probe, v.normal, v.direction, goal, v.pdf); }
        next_target = goal;
    }
    pass_image[pixel] = vec4<f32>(radiance, 1.0);
    atomicAdd(&counters.paths, 1u);
    if (max(max(radiance.x, radiance.y), radiance.z) > 0.0) { atomicAdd(&counters.nonzero, 1u); }
    atomicAdd(&counters.rays, rays);
    atomicAdd(&counters.vertices, vertices);
}

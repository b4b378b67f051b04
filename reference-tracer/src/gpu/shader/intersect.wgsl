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

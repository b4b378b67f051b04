// ---------------------------------------------------------------------------------
// The spatial × directional tree (guiding-core's tree/, uploaded as its FlatTree lays
// it out): a locate descends the binary tree over the scene's box; each leaf's quadtree
// over Lambert's equal-area square about the leaf's axis is sampled and evaluated by
// one descent (two where the sphere folds onto a normal off that axis). Learning
// appends records (leaf and half, normal, direction, target, pdf) to `q`, which the host
// reads after the pass, splats into the tree and refits; the refitted tree comes back
// up. The bindings it reads:
//   probe_positions  four cell probabilities per quadtree node;
//   probe_normals    four cell probabilities per node under the cosine product;
//   index_table      the spatial roots (3 words), three words per spatial node from
//                    word 3, four per leaf from params.tree_leaves_at, four children
//                    per quadtree node from params.tree_quad_at;
//   q                the record count, then TREE_RECORD_WORDS words per record.
// A region is the leaf index, with TREE_UPPER_HALF set where the point lies in the
// upper half along the leaf's next split (the host counts records per half).

const TREE_UPPER_HALF: u32 = 0x80000000u;
const TREE_MAX_DEPTH: u32 = 64u;
const TREE_RECORD_WORDS: u32 = 9u;
// 1 − 2⁻²⁴: the largest f32 below one.
const ONE_BELOW: f32 = 0.99999994;
const SQUARE_TO_SOLID_ANGLE: f32 = 4.0 * PI;
// The distribution's modes (guiding-core's HemisphereMode).
const TREE_HALF: u32 = 0u;
const TREE_FOLD: u32 = 1u;
const TREE_SPHERE: u32 = 2u;
const TREE_UNIFORM: u32 = 3u;

fn tree_leaf_word(leaf: u32, k: u32) -> u32 {
    return index_table[params.tree_leaves_at + 4u * leaf + k];
}

fn tree_child(node: u32, cell: u32) -> u32 {
    return index_table[params.tree_quad_at + 4u * node + cell];
}

// A cell's probability within its node: the tree's own, or under the cosine product.
fn tree_probability(node: u32, cell: u32, cosine: bool) -> f32 {
    if (cosine) { return probe_normals[4u * node + cell]; }
    return probe_positions[4u * node + cell];
}

fn tree_cosine_product() -> bool {
    return (params.tree_flags & TREE_FLAG_COSINE) != 0u;
}

// glam's max_position: the first axis of the largest component.
fn largest_axis(v: vec3<f32>) -> u32 {
    var axis = 0u;
    var largest = v.x;
    if (v.y > largest) { axis = 1u; largest = v.y; }
    if (v.z > largest) { axis = 2u; }
    return axis;
}

// SpatialDirectionalTree::locate: the leaf holding `point` (the nearest one outside the
// box) in the tree of the normal's axis where there is one per axis; NO_PROBE for a
// non-finite point or normal.
fn tree_locate(point: vec3<f32>, normal: vec3<f32>) -> u32 {
    if (!all(abs(normal) < vec3<f32>(INFINITY))) { return NO_PROBE; }
    let unit = (point - params.grid_low) * params.grid_cells_per_unit;
    if (!all(abs(unit) < vec3<f32>(INFINITY))) { return NO_PROBE; }
    var p = clamp(unit, vec3<f32>(0.0), vec3<f32>(ONE_BELOW));
    var tree = 0u;
    if ((params.tree_flags & TREE_FLAG_PER_AXIS) != 0u) { tree = largest_axis(abs(normal)); }
    var reference = index_table[tree];
    for (var depth = 0u; depth < TREE_MAX_DEPTH && (reference & TREE_LEAF) == 0u; depth += 1u) {
        let node = 3u + 3u * reference;
        let axis = min(index_table[node + 2u], 2u);
        // Doubling and subtracting one are exact: the point stays in its half's unit box.
        let x = p[axis] * 2.0;
        let high = x >= 1.0;
        p[axis] = select(x, x - 1.0, high);
        reference = index_table[node + select(0u, 1u, high)];
    }
    if ((reference & TREE_LEAF) == 0u) { return NO_PROBE; }
    let leaf = reference & ~TREE_LEAF;
    if (leaf >= params.guide_regions) { return NO_PROBE; }
    let upper = p[min(tree_leaf_word(leaf, 2u), 2u)] >= 0.5;
    return leaf | select(0u, TREE_UPPER_HALF, upper);
}

// square.rs's to_axis_frame and from_axis_frame: the leaf's axis as the polar z.
fn to_axis_frame(d: vec3<f32>, axis: u32) -> vec3<f32> {
    if (axis == 0u) { return vec3<f32>(d.y, d.z, d.x); }
    if (axis == 1u) { return vec3<f32>(d.z, d.x, d.y); }
    return d;
}

fn from_axis_frame(l: vec3<f32>, axis: u32) -> vec3<f32> {
    if (axis == 0u) { return vec3<f32>(l.z, l.x, l.y); }
    if (axis == 1u) { return vec3<f32>(l.y, l.z, l.x); }
    return l;
}

// The point of Lambert's equal-area square a direction maps to, about `axis`.
fn axis_square(d: vec3<f32>, axis: u32) -> vec2<f32> {
    let l = to_axis_frame(d, axis);
    let u = (l.z + 1.0) * 0.5;
    let v = atan2(l.y, l.x) * (0.5 / PI) + 0.5;
    return clamp(vec2<f32>(u, v), vec2<f32>(0.0), vec2<f32>(ONE_BELOW));
}

fn square_to_direction(p: vec2<f32>) -> vec3<f32> {
    let z = clamp(2.0 * p.x - 1.0, -1.0, 1.0);
    let r = sqrt(max(1.0 - z * z, 0.0));
    let angle = PI * (2.0 * p.y - 1.0);
    return vec3<f32>(r * cos(angle), r * sin(angle), z);
}

// quadtree::square_density_by: the density at square point `p` relative to uniform.
fn tree_square_density(root: u32, start: vec2<f32>, cosine: bool) -> f32 {
    var p = start;
    var node = root;
    var density = 1.0;
    for (var level = 0u; level < TREE_MAX_DEPTH; level += 1u) {
        let high = p >= vec2<f32>(0.5);
        let cell = select(0u, 1u, high.x) + select(0u, 2u, high.y);
        p = p * 2.0 - select(vec2<f32>(0.0), vec2<f32>(1.0), high);
        density *= 4.0 * tree_probability(node, cell, cosine);
        let child = tree_child(node, cell);
        if (child == 0u) { break; }
        node = child;
    }
    return density;
}

// What a pick leaves: the cell (or side) picked and the number rescaled within it.
struct Pick {
    index: u32,
    u: f32,
};

// quadtree::choose: between masses a and b with u; index 1 for b.
fn tree_choose(u: f32, a: f32, b: f32) -> Pick {
    var pick: Pick;
    let total = a + b;
    if (!(total > 0.0)) {
        pick.index = select(0u, 1u, u >= 0.5);
        pick.u = select(u * 2.0, u * 2.0 - 1.0, u >= 0.5);
        return pick;
    }
    let scaled = u * total;
    let high = scaled >= a && b > 0.0;
    pick.index = select(0u, 1u, high);
    pick.u = clamp((scaled - select(0.0, a, high)) / select(a, b, high), 0.0, ONE_BELOW);
    return pick;
}

// quadtree::pick_cell: one of a node's four cells by their probabilities with u.
fn tree_pick_cell(u: f32, node: u32, cosine: bool) -> Pick {
    var pick: Pick;
    let p = vec4<f32>(
        tree_probability(node, 0u, cosine),
        tree_probability(node, 1u, cosine),
        tree_probability(node, 2u, cosine),
        tree_probability(node, 3u, cosine),
    );
    let low_pair = p.x + p.y;
    let edges = vec4<f32>(0.0, p.x, low_pair, low_pair + p.z);
    let total = low_pair + (p.z + p.w);
    if (!(total > 0.0)) {
        pick.index = min(u32(u * 4.0), 3u);
        pick.u = clamp(u * 4.0 - f32(pick.index), 0.0, ONE_BELOW);
        return pick;
    }
    let scaled = u * total;
    // The edges reached, where mass lies above them: a prefix, the first always in it.
    let reached = (vec4<f32>(scaled) >= edges) & (edges < vec4<f32>(total));
    let count = select(0u, 1u, reached.y) + select(0u, 1u, reached.z) + select(0u, 1u, reached.w);
    pick.index = count;
    pick.u = clamp((scaled - edges[count]) / p[count], 0.0, ONE_BELOW);
    return pick;
}

struct SquareSample {
    p: vec2<f32>,
    density: f32,
};

// Where a sampling descent stands: the cell's corner and side in the square, the
// density of the cells picked so far, and the node below (or done at a leaf cell).
struct Walk {
    origin: vec2<f32>,
    size: f32,
    density: f32,
    node: u32,
    done: bool,
};

// quadtree::step_into: into cell `cell` of the walk's node.
fn tree_step(walk: Walk, cell: u32, cosine: bool) -> Walk {
    var next = walk;
    next.density *= 4.0 * tree_probability(walk.node, cell, cosine);
    next.size *= 0.5;
    next.origin += vec2<f32>(f32(cell & 1u), f32(cell >> 1u)) * next.size;
    next.node = tree_child(walk.node, cell);
    next.done = next.node == 0u;
    return next;
}

// quadtree::sample_square_by: a point drawn by the cell probabilities from u, with its
// density relative to uniform; `restricted` keeps it to the half u ≥ 1/2 (`high`) or
// u < 1/2 of the square.
fn tree_sample_square(root: u32, start: vec2<f32>, restricted: bool, high: bool, cosine: bool) -> SquareSample {
    var u = start;
    var walk = Walk(vec2<f32>(0.0), 1.0, 1.0, root, false);
    if (restricted) {
        let ix = select(0u, 1u, high);
        let pick = tree_choose(u.y, tree_probability(root, ix, cosine), tree_probability(root, ix + 2u, cosine));
        u.y = pick.u;
        walk = tree_step(walk, ix + 2u * pick.index, cosine);
    }
    // The levels take turns with the two numbers, u's then v's.
    for (var level = 0u; !walk.done && level < TREE_MAX_DEPTH; level += 1u) {
        var pick: Pick;
        if ((level & 1u) == 0u) {
            pick = tree_pick_cell(u.x, walk.node, cosine);
            u.x = pick.u;
        } else {
            pick = tree_pick_cell(u.y, walk.node, cosine);
            u.y = pick.u;
        }
        walk = tree_step(walk, pick.index, cosine);
    }
    // Kept inside the leaf cell: origin + u·size can round onto its far edge.
    let end = walk.origin + vec2<f32>(walk.size);
    let below = bitcast<vec2<f32>>(bitcast<vec2<u32>>(end) - vec2<u32>(1u));
    return SquareSample(min(walk.origin + u * walk.size, below), walk.density);
}

// A region's distribution: how it keeps to the normal's hemisphere.
struct TreeMode {
    kind: u32,
    high: bool,
    inverse_mass: f32,
    root: u32,
    axis: u32,
    mix: f32,
};

// TreeDistribution::new.
fn tree_mode(region: u32, normal: vec3<f32>) -> TreeMode {
    let leaf = region & ~TREE_UPPER_HALF;
    var mode: TreeMode;
    mode.root = tree_leaf_word(leaf, 0u);
    mode.axis = min(tree_leaf_word(leaf, 1u), 2u);
    mode.mix = params.uniform_mix;
    mode.high = false;
    mode.inverse_mass = 1.0;
    if ((params.tree_flags & TREE_FLAG_FOLD) == 0u) {
        mode.kind = TREE_SPHERE;
        return mode;
    }
    let along = normal[mode.axis];
    if (abs(along) < TREE_ALIGNED_COS) {
        mode.kind = TREE_FOLD;
        return mode;
    }
    mode.high = along > 0.0;
    let ix = select(0u, 1u, mode.high);
    let cosine = tree_cosine_product();
    let mass = tree_probability(mode.root, ix, cosine) + tree_probability(mode.root, ix + 2u, cosine);
    if (mass >= TREE_MIN_HALF_MASS) {
        mode.kind = TREE_HALF;
        mode.inverse_mass = 1.0 / mass;
    } else {
        mode.kind = TREE_UNIFORM;
        mode.mix = 1.0;
    }
    return mode;
}

// The quadtree's own density at a direction, per steradian, on the whole sphere.
fn tree_sphere_pdf(mode: TreeMode, d: vec3<f32>) -> f32 {
    return tree_square_density(mode.root, axis_square(d, mode.axis), false) / SQUARE_TO_SOLID_ANGLE;
}

fn tree_uniform_pdf(mode: TreeMode, normal: vec3<f32>, d: vec3<f32>) -> f32 {
    if (mode.kind == TREE_SPHERE) { return 1.0 / SQUARE_TO_SOLID_ANGLE; }
    return select(0.0, 0.5 / PI, dot(d, normal) >= 0.0);
}

// The tree's share's density at a direction, per steradian, in the mode.
fn tree_share_pdf(mode: TreeMode, normal: vec3<f32>, d: vec3<f32>) -> f32 {
    if (mode.kind == TREE_HALF) {
        let p = axis_square(d, mode.axis);
        if ((p.x >= 0.5) != mode.high) { return 0.0; }
        return tree_square_density(mode.root, p, tree_cosine_product()) * mode.inverse_mass / SQUARE_TO_SOLID_ANGLE;
    }
    if (mode.kind == TREE_FOLD) {
        let c = dot(d, normal);
        if (!(c >= 0.0)) { return 0.0; }
        return tree_sphere_pdf(mode, d) + tree_sphere_pdf(mode, d - normal * (2.0 * c));
    }
    if (mode.kind == TREE_SPHERE) { return tree_sphere_pdf(mode, d); }
    return 0.0;
}

fn tree_mode_pdf(mode: TreeMode, normal: vec3<f32>, d: vec3<f32>) -> f32 {
    var share = 0.0;
    if (mode.mix < 1.0) { share = tree_share_pdf(mode, normal, d); }
    return mode.mix * tree_uniform_pdf(mode, normal, d) + (1.0 - mode.mix) * share;
}

fn tree_pdf(region: u32, normal: vec3<f32>, wi: vec3<f32>) -> f32 {
    return tree_mode_pdf(tree_mode(region, normal), normal, wi);
}

// TreeDistribution::sample.
fn tree_sample(region: u32, normal: vec3<f32>, start: vec2<f32>) -> GuideSample {
    let mode = tree_mode(region, normal);
    let mix = mode.mix;
    var s: GuideSample;
    if (start.x < mix) {
        // The uniform share: over the normal's hemisphere, or the sphere.
        let ux = start.x / mix;
        var z = max(ux, MIN_SAMPLED_COS);
        if (mode.kind == TREE_SPHERE) { z = 1.0 - 2.0 * ux; }
        let r = sqrt(max(1.0 - z * z, 0.0));
        let angle = PI * (2.0 * start.y - 1.0);
        s.wi = to_world(frame_from_normal(normal), vec3<f32>(r * cos(angle), r * sin(angle), z));
        s.pdf = tree_mode_pdf(mode, normal, s.wi);
        return s;
    }
    let u = vec2<f32>(min((start.x - mix) / (1.0 - mix), ONE_BELOW), start.y);
    if (mode.kind == TREE_HALF) {
        let cosine = tree_cosine_product();
        let drawn = tree_sample_square(mode.root, u, true, mode.high, cosine);
        var p = drawn.p;
        var density = drawn.density;
        // Kept off the horizon, as the other samplers keep cos θ ≥ MIN_SAMPLED_COS.
        let edge = 0.5 * MIN_SAMPLED_COS;
        if (abs(p.x - 0.5) < edge) {
            p.x = select(0.5 - edge, 0.5 + edge, mode.high);
            density = tree_square_density(mode.root, p, cosine);
        }
        s.wi = from_axis_frame(square_to_direction(p), mode.axis);
        let tree = density * mode.inverse_mass / SQUARE_TO_SOLID_ANGLE;
        s.pdf = mix * tree_uniform_pdf(mode, normal, s.wi) + (1.0 - mix) * tree;
        return s;
    }
    let drawn = tree_sample_square(mode.root, u, false, false, false);
    let d = from_axis_frame(square_to_direction(drawn.p), mode.axis);
    let c = dot(d, normal);
    if (mode.kind == TREE_FOLD && abs(c) >= MIN_SAMPLED_COS) {
        // The folded pdf: the density drawn at one of the direction and its mirror, one
        // more descent at the other.
        let mirrored = d - normal * (2.0 * c);
        var folded = d;
        var descended = mirrored;
        if (c <= 0.0) {
            folded = normalize(mirrored);
            descended = folded;
        }
        let tree = drawn.density / SQUARE_TO_SOLID_ANGLE + tree_sphere_pdf(mode, descended);
        s.wi = folded;
        s.pdf = mix * tree_uniform_pdf(mode, normal, folded) + (1.0 - mix) * tree;
        return s;
    }
    s.wi = d;
    if (mode.kind == TREE_FOLD && c < MIN_SAMPLED_COS) {
        // Within reach of the horizon: mirrored in the tangent plane, kept just above it.
        s.wi = normalize(d - normal * (c - max(abs(c), MIN_SAMPLED_COS)));
    }
    s.pdf = tree_mode_pdf(mode, normal, s.wi);
    return s;
}

// Appends the record; the host splats it after the pass. Past the buffer's room the
// count still rises (the host says how many it lost) and the record is left out.
fn tree_learn(region: u32, normal: vec3<f32>, wi: vec3<f32>, goal: f32, pdf: f32) {
    let slot = atomicAdd(&q[0], 1u);
    if (slot >= params.record_capacity) { return; }
    let base = 1u + TREE_RECORD_WORDS * slot;
    var words = array<u32, 9>(
        region,
        bitcast<u32>(normal.x), bitcast<u32>(normal.y), bitcast<u32>(normal.z),
        bitcast<u32>(wi.x), bitcast<u32>(wi.y), bitcast<u32>(wi.z),
        bitcast<u32>(goal), bitcast<u32>(pdf),
    );
    for (var k = 0u; k < TREE_RECORD_WORDS; k += 1u) { atomicStore(&q[base + k], words[k]); }
}

// SpatialDirectionalTree::q: the radiance learned to arrive from `d`.
fn tree_q(mode: TreeMode, leaf: u32, d: vec3<f32>) -> f32 {
    return bitcast<f32>(tree_leaf_word(leaf, 3u)) * tree_sphere_pdf(mode, d);
}

// SpatialDirectionalTree::estimate_integral: Q at one cosine-distributed direction times
// the albedo on a diffuse surface, Q at one BSDF sample times its weight elsewhere.
fn tree_integral(region: u32, m: Material, shading: Shading, wo_local: vec3<f32>, u: vec2<f32>, u_lobe: f32) -> f32 {
    let mode = tree_mode(region, shading.frame.normal);
    let leaf = region & ~TREE_UPPER_HALF;
    var estimate = 0.0;
    if (m.kind == DIFFUSE) {
        let wi = to_world(frame_from_normal(shading.frame.normal), cosine_hemisphere(u));
        estimate = tree_q(mode, leaf, wi) * luminance(m.albedo.xyz);
    } else {
        let d = bsdf_direction(m, shading, wo_local, u, u_lobe);
        if (!d.ok) { return 0.0; }
        estimate = tree_q(mode, leaf, d.wi) * d.weight;
    }
    if (!(estimate < INFINITY)) { return 0.0; }
    return max(estimate, 0.0);
}

// The host refits the tree between passes.
fn tree_rebuild(region: u32) {}

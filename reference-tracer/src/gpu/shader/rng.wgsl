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

//! The C ABI with arbitrary arguments: a fuzzed config and mesh (or bounds, for the
//! volume, mixture and tree), then a fuzzed sequence
//! of calls with NaN/∞ numbers, stray regions, NULL outputs, odd buffer sizes and edited
//! saved buffers; inputs starting 0xE5 drive the environment guide instead. No call may
//! panic through (`LODESTAR_STATUS_INTERNAL_ERROR`) or crash,
//! and what a successful call returns is finite.
#![no_main]

use std::ffi::c_void;
use std::mem::MaybeUninit;
use std::ptr::{null, null_mut};

use libfuzzer_sys::fuzz_target;
use lodestar::*;

/// Reads numbers off the fuzzer's bytes; zeros once they run out.
struct Input<'a>(&'a [u8]);

impl Input<'_> {
    fn bytes<const N: usize>(&mut self) -> [u8; N] {
        let mut out = [0u8; N];
        let n = self.0.len().min(N);
        out[..n].copy_from_slice(&self.0[..n]);
        self.0 = &self.0[n..];
        out
    }
    fn u8(&mut self) -> u8 {
        self.bytes::<1>()[0]
    }
    fn u32(&mut self) -> u32 {
        u32::from_le_bytes(self.bytes())
    }
    fn f32(&mut self) -> f32 {
        f32::from_le_bytes(self.bytes())
    }
    fn vec3(&mut self) -> LodestarVec3 {
        LodestarVec3 { x: self.f32(), y: self.f32(), z: self.f32() }
    }
}

fn ok(status: LodestarStatus) -> bool {
    assert_ne!(status, LodestarStatus::InternalError, "a panic reached the C boundary");
    status == LodestarStatus::Ok
}

unsafe extern "C" fn eval_cos(user_data: *mut c_void, wi: LodestarVec3, _wo: LodestarVec3) -> f32 {
    // The fuzzer's value for the BSDF, scaled by the cosine about +y.
    let scale = unsafe { *(user_data as *const f32) };
    scale * wi.y.max(0.0)
}

fn fuzzed_config(input: &mut Input) -> LodestarGuideConfig {
    let mut config = MaybeUninit::uninit();
    assert!(ok(unsafe { lodestar_guide_config_default(config.as_mut_ptr()) }));
    let mut config = unsafe { config.assume_init() };
    let spoil = input.u32();
    let mut field = 0;
    let mut next = || {
        field += 1;
        spoil & (1 << field) != 0
    };
    if next() {
        config.struct_size = input.u32()
    }
    if next() {
        config.structure = input.u32()
    }
    if next() {
        config.budget_bytes = input.u32() as u64
    }
    if next() {
        config.region_count = (input.u8() % 64) as u64
    }
    if next() {
        config.mapping = input.u32()
    }
    if next() {
        config.resolution = [input.u8() as u32, input.u8() as u32]
    }
    if next() {
        config.two_sided = input.u32()
    }
    if next() {
        config.max_normal_angle_deg = input.f32()
    }
    if next() {
        config.max_search_rings = input.u32()
    }
    if next() {
        config.initial_q = input.f32()
    }
    if next() {
        config.q_floor = input.f32()
    }
    if next() {
        config.uniform_mix = input.f32()
    }
    if next() {
        config.sampling_exponent = input.f32()
    }
    if next() {
        config.learning_rate = input.u32()
    }
    if next() {
        config.learning_rate_parameter = input.f32()
    }
    if next() {
        config.integral_estimator = input.u32()
    }
    config
}

/// The environment guide with a fuzzed config, map, sun and calls.
fn environment_guide(input: &mut Input) {
    let mut config = MaybeUninit::uninit();
    assert!(ok(unsafe { lodestar_env_guide_config_default(config.as_mut_ptr()) }));
    let mut config = unsafe { config.assume_init() };
    config.budget_bytes = (input.u32() % (256 << 10)) as u64;
    config.tiles = [input.u8() as u32 % 40, input.u8() as u32 % 24];
    if input.u8() & 1 != 0 {
        (config.power_mix, config.uniform_mix) = (input.f32(), input.f32());
    }
    let (width, height) = (1 + input.u8() as usize % 32, 1 + input.u8() as usize % 16);
    let luminance: Vec<f32> = (0..width * height).map(|_| input.f32().abs().min(1e6)).collect();
    let sun = LodestarSunDisk { direction: input.vec3(), angular_radius: input.f32(), luminance: input.f32() };
    let sun_pointer = if input.u8() & 1 != 0 { &sun as *const _ } else { null() };
    let (low, high) = (input.vec3(), input.vec3());
    let mut guide = null_mut();
    let created = unsafe {
        lodestar_env_guide_create(&config, low, high, luminance.as_ptr(), width, height, sun_pointer, &mut guide)
    };
    if !ok(created) {
        assert!(guide.is_null());
        return;
    }
    let mut sample = LodestarEnvSample::default();
    while !input.0.is_empty() {
        let cell = input.u32() % 64;
        unsafe {
            match input.u8() % 5 {
                0 => {
                    let mut found = 0;
                    ok(lodestar_env_guide_cell(guide, input.vec3(), &mut found));
                }
                1 => {
                    let mut drawn = LodestarEnvSample::default();
                    if ok(lodestar_env_guide_sample(guide, cell, input.f32(), input.f32(), input.f32(), &mut drawn)) {
                        assert!(drawn.pdf.is_finite() && drawn.pdf > 0.0, "{drawn:?}");
                        sample = drawn;
                    }
                }
                2 => {
                    let (mut pdf, direction) = (-1.0, input.vec3());
                    if ok(lodestar_env_guide_pdf(guide, cell, direction, &mut pdf)) {
                        assert!(pdf.is_finite() && pdf >= 0.0, "{pdf} at {direction:?} from cell {cell}");
                    }
                }
                3 => {
                    let mut outcome = LodestarUpdateOutcome::Accepted;
                    if input.u8() & 1 != 0 {
                        sample.lobe = input.u32() % 1024;
                    }
                    ok(lodestar_env_guide_update(guide, cell, &sample, input.f32(), &mut outcome));
                }
                _ => {
                    assert!(ok(lodestar_env_guide_rebuild(guide)));
                    let mut size = 0usize;
                    assert!(ok(lodestar_env_guide_save(guide, null_mut(), 0, &mut size)));
                    let mut bytes = vec![0u8; size];
                    assert!(ok(lodestar_env_guide_save(guide, bytes.as_mut_ptr(), size, &mut size)));
                    if input.u8() & 1 != 0 {
                        let position = input.u32() as usize % bytes.len();
                        bytes[position] ^= input.u8();
                    }
                    let mut loaded = null_mut();
                    let status = lodestar_env_guide_load(
                        &config,
                        bytes.as_ptr(),
                        bytes.len(),
                        luminance.as_ptr(),
                        width,
                        height,
                        sun_pointer,
                        &mut loaded,
                    );
                    if ok(status) {
                        assert!(ok(lodestar_env_guide_release(loaded)));
                    }
                }
            }
        }
    }
    assert!(ok(unsafe { lodestar_env_guide_release(guide) }));
}

fuzz_target!(|data: &[u8]| {
    let mut input = Input(data);
    if data.first() == Some(&0xE5) {
        input.u8();
        return environment_guide(&mut input);
    }
    let mut config = fuzzed_config(&mut input);
    if config.region_count == 0 && config.budget_bytes > 1 << 20 {
        config.region_count = 64; // keeps each run small; the budget path is covered below 1 MiB
    }
    let mut positions = [0.0f32, 0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 0.0, 1.0, 1.0, 0.0, 0.0];
    let mut indices = [0u32, 1, 2, 0, 2, 3];
    let geometry = input.u8();
    if geometry & 1 != 0 {
        positions.iter_mut().for_each(|p| *p = input.f32());
    }
    if geometry & 2 != 0 {
        indices.iter_mut().for_each(|i| *i = input.u32() % 6);
    }
    let null_config = geometry & 4 != 0;
    let config_pointer = if null_config { null() } else { &config as *const _ };
    let mut guide = null_mut();
    let (low, high) = if geometry & 1 != 0 {
        (input.vec3(), input.vec3())
    } else {
        (LodestarVec3::default(), LodestarVec3 { x: 1.0, y: 1.0, z: 1.0 })
    };
    // Small budgets keep each run quick; the other structures' configs are their defaults.
    let created = unsafe {
        match (geometry >> 3) % 4 {
            0 => lodestar_guide_create(config_pointer, positions.as_ptr(), 4, indices.as_ptr(), 2, &mut guide),
            1 => {
                let mut c = MaybeUninit::uninit();
                assert!(ok(lodestar_volume_config_default(c.as_mut_ptr())));
                let c = LodestarVolumeConfig { budget_bytes: 64 << 10, ..c.assume_init() };
                lodestar_guide_create_volume(if null_config { null() } else { &c }, low, high, &mut guide)
            }
            2 => {
                let mut c = MaybeUninit::uninit();
                assert!(ok(lodestar_mixture_config_default(c.as_mut_ptr())));
                let c = LodestarMixtureConfig { budget_bytes: 64 << 10, ..c.assume_init() };
                lodestar_guide_create_mixture(if null_config { null() } else { &c }, low, high, &mut guide)
            }
            _ => {
                let mut c = MaybeUninit::uninit();
                assert!(ok(lodestar_tree_config_default(c.as_mut_ptr())));
                let c = LodestarTreeConfig { budget_bytes: 256 << 10, min_split_records: 16, ..c.assume_init() };
                lodestar_guide_create_tree(if null_config { null() } else { &c }, low, high, &mut guide)
            }
        }
    };
    if !ok(created) {
        assert!(guide.is_null());
        return;
    }
    let mut region = LodestarRegion { index: LODESTAR_NO_REGION, flags: 0, normal: LodestarVec3::default() };
    while !input.0.is_empty() {
        let operation = input.u8();
        if operation & 0x80 != 0 {
            let index = input.u32();
            let index = if operation & 0x40 != 0 { index } else { index % 1024 };
            region = LodestarRegion { index, flags: input.u32(), normal: input.vec3() };
        }
        unsafe {
            match operation % 10 {
                0 => {
                    let mut found = region;
                    if ok(lodestar_guide_locate(guide, input.vec3(), input.vec3(), &mut found)) {
                        region = found;
                    }
                }
                1 => {
                    let mut sample = LodestarDirectionSample::default();
                    if ok(lodestar_guide_sample(guide, region, input.f32(), input.f32(), &mut sample)) {
                        assert!(
                            sample.pdf.is_finite() && sample.pdf > 0.0,
                            "{sample:?} structure {} region {region:?}",
                            (geometry >> 3) % 4
                        );
                    }
                }
                2 => {
                    let mut pdf = -1.0;
                    if ok(lodestar_guide_pdf(guide, region, input.vec3(), &mut pdf)) {
                        assert!(pdf.is_finite() && pdf >= 0.0, "{pdf}");
                    }
                }
                3 => {
                    let mut outcome = LodestarUpdateOutcome::Accepted;
                    ok(lodestar_guide_update(guide, region, input.vec3(), input.f32(), &mut outcome));
                }
                4 => {
                    let mut outcome = LodestarUpdateOutcome::Accepted;
                    let (direction, target, pdf) = (input.vec3(), input.f32(), input.f32());
                    ok(lodestar_guide_update_sampled(guide, region, direction, target, pdf, &mut outcome));
                }
                5 => {
                    let mut value = -1.0;
                    let (normal, albedo) = (input.vec3(), input.f32());
                    let status = lodestar_guide_estimate_integral_lambertian(
                        guide, region, normal, albedo, 0.5, 0.5, &mut value,
                    );
                    if ok(status) {
                        assert!(value.is_finite() && value >= 0.0, "{value}");
                    }
                }
                6 => {
                    let mut value = -1.0;
                    let mut scale = input.f32();
                    let (wo, u0, u1) = (input.vec3(), input.f32(), input.f32());
                    let user = &mut scale as *mut f32 as *mut c_void;
                    if ok(lodestar_guide_estimate_integral(guide, region, wo, Some(eval_cos), user, u0, u1, &mut value))
                    {
                        assert!(value.is_finite() && value >= 0.0, "{value}");
                    }
                }
                7 => {
                    assert!(ok(lodestar_guide_rebuild(guide)));
                    let valid = ok(lodestar_guide_validate(guide));
                    let why = std::ffi::CStr::from_ptr(lodestar_last_error()).to_string_lossy();
                    assert!(valid, "a rebuilt guide (structure {}) validates: {why}", (geometry >> 3) % 4);
                }
                8 => {
                    let mut stats = LodestarGuideStats::default();
                    assert!(ok(lodestar_guide_stats(guide, &mut stats)));
                    assert_eq!(lodestar_guide_stats(guide, null_mut()), LodestarStatus::NullArgument);
                }
                _ => {
                    let mut size = 0usize;
                    assert!(ok(lodestar_guide_serialized_size(guide, &mut size)));
                    let capacity = (input.u32() as usize) % (size + 16);
                    let mut buffer = vec![0u8; capacity.max(1)];
                    let mut written = 0usize;
                    if ok(lodestar_guide_save(guide, buffer.as_mut_ptr(), capacity, &mut written)) {
                        buffer.truncate(written);
                        let edits = input.u8() % 4;
                        for _ in 0..edits {
                            let position = input.u32() as usize % buffer.len();
                            buffer[position] = input.u8();
                        }
                        let mut loaded = null_mut();
                        if ok(lodestar_guide_load(buffer.as_ptr(), buffer.len(), &mut loaded)) {
                            assert!(ok(lodestar_guide_validate(loaded)));
                            // The copy, edited or not, takes in the guide (or says why not)
                            // and stays valid.
                            if ok(lodestar_guide_merge(loaded, guide)) {
                                assert!(ok(lodestar_guide_validate(loaded)));
                            }
                            assert!(ok(lodestar_guide_release(loaded)));
                        }
                    } else {
                        assert!(written == size, "BUFFER_TOO_SMALL reports the size needed");
                    }
                }
            }
        }
    }
    assert!(ok(unsafe { lodestar_guide_release(guide) }));
});

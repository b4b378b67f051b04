//! The part of Embree 4's C API the adapter calls, declared here rather than taken from
//! `embree4-sys` (whose 4.2 headers lack `RTCHit::instPrimID`, so Embree ≥ 4.3 would write
//! 96 bytes into its 80-byte `RTCRayHit`). Layouts match `rtcore_ray.h` of Embree 4.3+
//! with `RTC_MAX_INSTANCE_LEVEL_COUNT` = 1; the tests pin sizes and offsets.
#![allow(non_camel_case_types, non_snake_case, missing_docs)]

use std::ffi::{c_char, c_uint, c_void};

pub type RTCDevice = *mut c_void;
pub type RTCScene = *mut c_void;
pub type RTCGeometry = *mut c_void;

pub const RTC_INVALID_GEOMETRY_ID: c_uint = u32::MAX;

/// `enum RTCError`.
pub type RTCError = u32;
pub const RTC_ERROR_NONE: RTCError = 0;

/// `enum RTCSceneFlags`.
pub const RTC_SCENE_FLAG_ROBUST: u32 = 1 << 2;
/// `enum RTCBuildQuality`.
pub const RTC_BUILD_QUALITY_HIGH: u32 = 2;
/// `enum RTCGeometryType`.
pub const RTC_GEOMETRY_TYPE_TRIANGLE: u32 = 0;
/// `enum RTCBufferType`.
pub const RTC_BUFFER_TYPE_INDEX: u32 = 0;
pub const RTC_BUFFER_TYPE_VERTEX: u32 = 1;
/// `enum RTCFormat`.
pub const RTC_FORMAT_UINT3: u32 = 0x5003;
pub const RTC_FORMAT_FLOAT3: u32 = 0x9003;

pub type RTCErrorFunction = Option<unsafe extern "C" fn(user: *mut c_void, code: RTCError, message: *const c_char)>;

#[repr(C, align(16))]
#[derive(Clone, Copy, Debug, Default)]
pub struct RTCRay {
    pub org_x: f32,
    pub org_y: f32,
    pub org_z: f32,
    pub tnear: f32,
    pub dir_x: f32,
    pub dir_y: f32,
    pub dir_z: f32,
    pub time: f32,
    pub tfar: f32,
    pub mask: c_uint,
    pub id: c_uint,
    pub flags: c_uint,
}

#[repr(C, align(16))]
#[derive(Clone, Copy, Debug, Default)]
pub struct RTCHit {
    pub Ng_x: f32,
    pub Ng_y: f32,
    pub Ng_z: f32,
    pub u: f32,
    pub v: f32,
    pub primID: c_uint,
    pub geomID: c_uint,
    pub instID: [c_uint; 1],
    pub instPrimID: [c_uint; 1],
}

#[repr(C, align(16))]
#[derive(Clone, Copy, Debug, Default)]
pub struct RTCRayHit {
    pub ray: RTCRay,
    pub hit: RTCHit,
}

/// Lanes of Embree's widest ray packet.
pub const PACKET_LANES: usize = 16;

/// `struct RTCRay16`: 16 rays, each field a lane array (structure of arrays).
#[repr(C, align(64))]
#[derive(Clone, Copy, Debug, Default)]
pub struct RTCRay16 {
    pub org_x: [f32; PACKET_LANES],
    pub org_y: [f32; PACKET_LANES],
    pub org_z: [f32; PACKET_LANES],
    pub tnear: [f32; PACKET_LANES],
    pub dir_x: [f32; PACKET_LANES],
    pub dir_y: [f32; PACKET_LANES],
    pub dir_z: [f32; PACKET_LANES],
    pub time: [f32; PACKET_LANES],
    pub tfar: [f32; PACKET_LANES],
    pub mask: [c_uint; PACKET_LANES],
    pub id: [c_uint; PACKET_LANES],
    pub flags: [c_uint; PACKET_LANES],
}

/// `struct RTCHit16`, with `RTC_MAX_INSTANCE_LEVEL_COUNT` = 1.
#[repr(C, align(64))]
#[derive(Clone, Copy, Debug, Default)]
pub struct RTCHit16 {
    pub Ng_x: [f32; PACKET_LANES],
    pub Ng_y: [f32; PACKET_LANES],
    pub Ng_z: [f32; PACKET_LANES],
    pub u: [f32; PACKET_LANES],
    pub v: [f32; PACKET_LANES],
    pub primID: [c_uint; PACKET_LANES],
    pub geomID: [c_uint; PACKET_LANES],
    pub instID: [[c_uint; PACKET_LANES]; 1],
    pub instPrimID: [[c_uint; PACKET_LANES]; 1],
}

/// `struct RTCRayHit16`.
#[repr(C, align(64))]
#[derive(Clone, Copy, Debug, Default)]
pub struct RTCRayHit16 {
    pub ray: RTCRay16,
    pub hit: RTCHit16,
}

extern "C" {
    pub fn rtcNewDevice(config: *const c_char) -> RTCDevice;
    pub fn rtcReleaseDevice(device: RTCDevice);
    pub fn rtcGetDeviceError(device: RTCDevice) -> RTCError;
    pub fn rtcSetDeviceErrorFunction(device: RTCDevice, function: RTCErrorFunction, user: *mut c_void);
    pub fn rtcNewScene(device: RTCDevice) -> RTCScene;
    pub fn rtcReleaseScene(scene: RTCScene);
    pub fn rtcSetSceneFlags(scene: RTCScene, flags: u32);
    pub fn rtcSetSceneBuildQuality(scene: RTCScene, quality: u32);
    pub fn rtcCommitScene(scene: RTCScene);
    pub fn rtcNewGeometry(device: RTCDevice, kind: u32) -> RTCGeometry;
    pub fn rtcReleaseGeometry(geometry: RTCGeometry);
    pub fn rtcSetNewGeometryBuffer(
        geometry: RTCGeometry,
        kind: u32,
        slot: c_uint,
        format: u32,
        byte_stride: usize,
        item_count: usize,
    ) -> *mut c_void;
    pub fn rtcCommitGeometry(geometry: RTCGeometry);
    pub fn rtcAttachGeometry(scene: RTCScene, geometry: RTCGeometry) -> c_uint;
    /// Embree 4: no context argument; `args` may be NULL.
    pub fn rtcIntersect1(scene: RTCScene, rayhit: *mut RTCRayHit, args: *mut c_void);
    pub fn rtcOccluded1(scene: RTCScene, ray: *mut RTCRay, args: *mut c_void);
    /// `valid`: 16 lanes, -1 where the lane's ray is traced, 0 where it is not (64-byte
    /// aligned).
    pub fn rtcIntersect16(valid: *const i32, scene: RTCScene, rayhit: *mut RTCRayHit16, args: *mut c_void);
    pub fn rtcOccluded16(valid: *const i32, scene: RTCScene, ray: *mut RTCRay16, args: *mut c_void);
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::mem::{align_of, offset_of, size_of};

    #[test]
    fn layouts_match_embree_4_3_and_later() {
        assert_eq!(size_of::<RTCRay>(), 48);
        assert_eq!(size_of::<RTCHit>(), 48);
        assert_eq!(size_of::<RTCRayHit>(), 96);
        assert_eq!(align_of::<RTCRayHit>(), 16);
        assert_eq!(offset_of!(RTCRay, tnear), 12);
        assert_eq!(offset_of!(RTCRay, tfar), 32);
        assert_eq!(offset_of!(RTCRay, flags), 44);
        assert_eq!(offset_of!(RTCHit, u), 12);
        assert_eq!(offset_of!(RTCHit, primID), 20);
        assert_eq!(offset_of!(RTCHit, geomID), 24);
        assert_eq!(offset_of!(RTCHit, instID), 28);
        assert_eq!(offset_of!(RTCHit, instPrimID), 32);
        assert_eq!(offset_of!(RTCRayHit, hit), 48);
        assert_eq!(size_of::<RTCRay16>(), 12 * 64);
        assert_eq!(size_of::<RTCHit16>(), 9 * 64);
        assert_eq!(align_of::<RTCRayHit16>(), 64);
        assert_eq!(offset_of!(RTCRay16, tfar), 8 * 64);
        assert_eq!(offset_of!(RTCHit16, geomID), 6 * 64);
        assert_eq!(offset_of!(RTCRayHit16, hit), 12 * 64);
    }
}

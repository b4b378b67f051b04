//! [`EmbreeIntersector`]: an Embree 4 device and scene behind the `Intersector` trait.

use std::ffi::{c_char, c_void, CStr};
use std::fmt;
use std::sync::Mutex;

use glam::Vec2;
use guiding_core::{Hit, Intersector, Ray, Triangle};

use crate::sys;

/// Something Embree reported through its device error callback, or a call that failed.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct EmbreeError {
    /// Embree's `RTCError` code (0 when the failure was a NULL handle).
    pub code: u32,
    /// What Embree said, with the call that failed.
    pub message: String,
}

impl fmt::Display for EmbreeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "Embree error {}: {}", self.code, self.message)
    }
}

impl std::error::Error for EmbreeError {}

/// Errors the device callback collected; boxed so its address stays fixed for Embree.
#[derive(Default)]
struct ErrorLog {
    errors: Mutex<Vec<EmbreeError>>,
}

unsafe extern "C" fn record_error(user: *mut c_void, code: sys::RTCError, message: *const c_char) {
    // SAFETY: `user` is the ErrorLog registered with the device, alive while it is.
    let log = unsafe { &*(user as *const ErrorLog) };
    let message = if message.is_null() {
        String::new()
    } else {
        // SAFETY: Embree passes a NUL-terminated string valid during the call.
        unsafe { CStr::from_ptr(message) }.to_string_lossy().into_owned()
    };
    if let Ok(mut errors) = log.errors.lock() {
        errors.push(EmbreeError { code, message });
    }
}

/// Closest-hit and occlusion queries over a triangle list, through Embree 4.
pub struct EmbreeIntersector {
    device: sys::RTCDevice,
    scene: sys::RTCScene,
    /// Index in the caller's slice of each triangle Embree holds (non-finite ones are left out).
    original_index: Vec<u32>,
    /// Whether `original_index` is the identity (every triangle finite): hits then skip
    /// the lookup, a cache miss per hit in large scenes.
    identity: bool,
    log: Box<ErrorLog>,
}

// SAFETY: a committed Embree scene may be traversed from any number of threads at once,
// and the handles are only released in `drop`, which has the value to itself.
unsafe impl Send for EmbreeIntersector {}
unsafe impl Sync for EmbreeIntersector {}

impl EmbreeIntersector {
    /// Builds a robust (watertight), high-quality Embree scene over `triangles`. Triangles
    /// with a non-finite coordinate are left out and never hit; hits report indices into
    /// `triangles`. Any error Embree reports fails the build.
    pub fn build(triangles: &[Triangle]) -> Result<Self, EmbreeError> {
        let log = Box::<ErrorLog>::default();
        // SAFETY: NULL config selects the defaults.
        let device = unsafe { sys::rtcNewDevice(std::ptr::null()) };
        if device.is_null() {
            return Err(EmbreeError { code: 0, message: "rtcNewDevice returned NULL".into() });
        }
        let log_pointer = &*log as *const ErrorLog as *mut c_void;
        // SAFETY: the device is valid; the log outlives it (released in drop first).
        unsafe { sys::rtcSetDeviceErrorFunction(device, Some(record_error), log_pointer) };
        let mut intersector =
            Self { device, scene: std::ptr::null_mut(), original_index: Vec::new(), identity: true, log };
        // SAFETY: the device is valid.
        intersector.scene = unsafe { sys::rtcNewScene(device) };
        intersector.check("rtcNewScene")?;
        intersector.original_index =
            (0..triangles.len() as u32).filter(|&i| triangles[i as usize].is_finite()).collect();
        intersector.identity = intersector.original_index.len() == triangles.len();
        // SAFETY: scene valid; flags and quality are values of their enums.
        unsafe {
            sys::rtcSetSceneFlags(intersector.scene, sys::RTC_SCENE_FLAG_ROBUST);
            sys::rtcSetSceneBuildQuality(intersector.scene, sys::RTC_BUILD_QUALITY_HIGH);
        }
        if !intersector.original_index.is_empty() {
            intersector.attach_triangles(triangles)?;
        }
        // SAFETY: scene valid.
        unsafe { sys::rtcCommitScene(intersector.scene) };
        intersector.check("rtcCommitScene")?;
        Ok(intersector)
    }

    fn attach_triangles(&mut self, triangles: &[Triangle]) -> Result<(), EmbreeError> {
        let count = self.original_index.len();
        // SAFETY: device valid; the geometry is released after attaching (the scene keeps
        // its own reference). Buffers come from Embree, sized for `count` items of the
        // given stride, and are written in bounds below.
        unsafe {
            let geometry = sys::rtcNewGeometry(self.device, sys::RTC_GEOMETRY_TYPE_TRIANGLE);
            self.check("rtcNewGeometry")?;
            let vertices = sys::rtcSetNewGeometryBuffer(
                geometry,
                sys::RTC_BUFFER_TYPE_VERTEX,
                0,
                sys::RTC_FORMAT_FLOAT3,
                12,
                3 * count,
            ) as *mut [f32; 3];
            let indices =
                sys::rtcSetNewGeometryBuffer(geometry, sys::RTC_BUFFER_TYPE_INDEX, 0, sys::RTC_FORMAT_UINT3, 12, count)
                    as *mut [u32; 3];
            if vertices.is_null() || indices.is_null() {
                sys::rtcReleaseGeometry(geometry);
                self.check("rtcSetNewGeometryBuffer")?;
                return Err(EmbreeError { code: 0, message: "rtcSetNewGeometryBuffer returned NULL".into() });
            }
            let vertices = std::slice::from_raw_parts_mut(vertices, 3 * count);
            let indices = std::slice::from_raw_parts_mut(indices, count);
            for (slot, &original) in self.original_index.iter().enumerate() {
                for (corner, v) in triangles[original as usize].vertices.iter().enumerate() {
                    vertices[3 * slot + corner] = v.to_array();
                }
                let first = 3 * slot as u32;
                indices[slot] = [first, first + 1, first + 2];
            }
            sys::rtcCommitGeometry(geometry);
            sys::rtcAttachGeometry(self.scene, geometry);
            sys::rtcReleaseGeometry(geometry);
        }
        self.check("attaching the triangles")
    }

    /// Fails with the first error Embree recorded (or returned) since the last check.
    fn check(&self, call: &str) -> Result<(), EmbreeError> {
        let mut errors = self.log.errors.lock().map(|mut e| std::mem::take(&mut *e)).unwrap_or_default();
        // SAFETY: the device is valid.
        let code = unsafe { sys::rtcGetDeviceError(self.device) };
        if code != sys::RTC_ERROR_NONE && errors.is_empty() {
            errors.push(EmbreeError { code, message: String::new() });
        }
        match errors.into_iter().next() {
            None => Ok(()),
            Some(mut e) => {
                e.message = format!("{call}: {}", e.message);
                Err(e)
            }
        }
    }

    /// Errors Embree reported after the build (during traversal), if any; clears them.
    pub fn take_errors(&self) -> Vec<EmbreeError> {
        self.log.errors.lock().map(|mut e| std::mem::take(&mut *e)).unwrap_or_default()
    }

    /// Number of triangles in the scene (finite ones).
    pub fn triangle_count(&self) -> usize {
        self.original_index.len()
    }

    /// The raw Embree scene handle, for callers that trace it directly (valid while
    /// `self` lives).
    pub fn scene(&self) -> sys::RTCScene {
        self.scene
    }

    /// Embree accepts `tnear ≤ t ≤ tfar`; the trait asks for `t_min < t < t_max`.
    #[inline]
    fn embree_ray(ray: &Ray) -> sys::RTCRay {
        let below = |t: f32| if t.is_finite() && t > 0.0 { f32::from_bits(t.to_bits() - 1) } else { t };
        let above = |t: f32| if t.is_finite() && t > 0.0 { f32::from_bits(t.to_bits() + 1) } else { t };
        sys::RTCRay {
            org_x: ray.origin.x,
            org_y: ray.origin.y,
            org_z: ray.origin.z,
            tnear: above(ray.t_min.max(0.0)),
            dir_x: ray.direction.x,
            dir_y: ray.direction.y,
            dir_z: ray.direction.z,
            time: 0.0,
            tfar: below(ray.t_max),
            mask: u32::MAX,
            id: 0,
            flags: 0,
        }
    }
}

impl Intersector for EmbreeIntersector {
    #[inline]
    fn intersect(&self, ray: &Ray) -> Option<Hit> {
        if !ray.is_traceable() || self.original_index.is_empty() {
            return None;
        }
        let mut ray_hit = sys::RTCRayHit {
            ray: Self::embree_ray(ray),
            hit: sys::RTCHit {
                geomID: sys::RTC_INVALID_GEOMETRY_ID,
                instID: [sys::RTC_INVALID_GEOMETRY_ID],
                ..Default::default()
            },
        };
        // SAFETY: committed scene; `ray_hit` is a 16-byte-aligned 96-byte RTCRayHit.
        unsafe { sys::rtcIntersect1(self.scene, &mut ray_hit, std::ptr::null_mut()) };
        (ray_hit.hit.geomID != sys::RTC_INVALID_GEOMETRY_ID).then(|| Hit {
            t: ray_hit.ray.tfar,
            primitive: if self.identity {
                ray_hit.hit.primID
            } else {
                self.original_index[ray_hit.hit.primID as usize]
            },
            barycentrics: Vec2::new(ray_hit.hit.u, ray_hit.hit.v),
        })
    }

    #[inline]
    fn occluded(&self, ray: &Ray) -> bool {
        if !ray.is_traceable() || self.original_index.is_empty() {
            return false;
        }
        let mut embree_ray = Self::embree_ray(ray);
        // SAFETY: committed scene; `embree_ray` is a 16-byte-aligned RTCRay.
        unsafe { sys::rtcOccluded1(self.scene, &mut embree_ray, std::ptr::null_mut()) };
        embree_ray.tfar == f32::NEG_INFINITY
    }

    /// Sixteen rays at a time through `rtcIntersect16`.
    fn intersect_many(&self, rays: &[Ray], hits: &mut [Option<Hit>]) {
        let count = rays.len().min(hits.len());
        if self.original_index.is_empty() {
            hits[..count].fill(None);
            return;
        }
        let mut packet = sys::RTCRayHit16::default();
        for (rays, hits) in rays[..count].chunks(sys::PACKET_LANES).zip(hits[..count].chunks_mut(sys::PACKET_LANES)) {
            let valid = Self::fill_packet(rays, &mut packet.ray);
            packet.hit.geomID = [sys::RTC_INVALID_GEOMETRY_ID; sys::PACKET_LANES];
            packet.hit.instID = [[sys::RTC_INVALID_GEOMETRY_ID; sys::PACKET_LANES]];
            // SAFETY: committed scene; `packet` and `valid` are 64-byte-aligned RTCRayHit16
            // and lane mask, every lane the mask turns on filled.
            unsafe { sys::rtcIntersect16(valid.0.as_ptr(), self.scene, &mut packet, std::ptr::null_mut()) };
            for (lane, hit) in hits.iter_mut().enumerate() {
                let found = valid.0[lane] != 0 && packet.hit.geomID[lane] != sys::RTC_INVALID_GEOMETRY_ID;
                *hit = found.then(|| {
                    let primitive = packet.hit.primID[lane];
                    Hit {
                        t: packet.ray.tfar[lane],
                        primitive: if self.identity { primitive } else { self.original_index[primitive as usize] },
                        barycentrics: Vec2::new(packet.hit.u[lane], packet.hit.v[lane]),
                    }
                });
            }
        }
    }

    /// Sixteen rays at a time through `rtcOccluded16`.
    fn occluded_many(&self, rays: &[Ray], occluded: &mut [bool]) {
        let count = rays.len().min(occluded.len());
        if self.original_index.is_empty() {
            occluded[..count].fill(false);
            return;
        }
        let mut packet = sys::RTCRay16::default();
        for (rays, occluded) in
            rays[..count].chunks(sys::PACKET_LANES).zip(occluded[..count].chunks_mut(sys::PACKET_LANES))
        {
            let valid = Self::fill_packet(rays, &mut packet);
            // SAFETY: committed scene; `packet` and `valid` are 64-byte-aligned RTCRay16 and
            // lane mask, every lane the mask turns on filled.
            unsafe { sys::rtcOccluded16(valid.0.as_ptr(), self.scene, &mut packet, std::ptr::null_mut()) };
            for (lane, blocked) in occluded.iter_mut().enumerate() {
                *blocked = valid.0[lane] != 0 && packet.tfar[lane] == f32::NEG_INFINITY;
            }
        }
    }
}

/// A packet's lane mask: -1 traces the lane, 0 leaves it out (Embree wants it aligned
/// as the packet is).
#[repr(C, align(64))]
struct LaneMask([i32; sys::PACKET_LANES]);

impl EmbreeIntersector {
    /// Fills `packet`'s rays from `rays` (at most [`sys::PACKET_LANES`]) and returns the
    /// lane mask: the lanes past `rays` and those holding an untraceable ray are off.
    #[inline]
    fn fill_packet(rays: &[Ray], packet: &mut sys::RTCRay16) -> LaneMask {
        let mut valid = LaneMask([0; sys::PACKET_LANES]);
        for (lane, ray) in rays.iter().enumerate().take(sys::PACKET_LANES) {
            let r = Self::embree_ray(ray);
            packet.org_x[lane] = r.org_x;
            packet.org_y[lane] = r.org_y;
            packet.org_z[lane] = r.org_z;
            packet.tnear[lane] = r.tnear;
            packet.dir_x[lane] = r.dir_x;
            packet.dir_y[lane] = r.dir_y;
            packet.dir_z[lane] = r.dir_z;
            packet.time[lane] = r.time;
            packet.tfar[lane] = r.tfar;
            packet.mask[lane] = r.mask;
            packet.id[lane] = r.id;
            packet.flags[lane] = r.flags;
            valid.0[lane] = if ray.is_traceable() { -1 } else { 0 };
        }
        valid
    }
}

impl Drop for EmbreeIntersector {
    fn drop(&mut self) {
        // SAFETY: handles from build, released once; the scene before its device, and the
        // error log (freed after this) outlives both.
        unsafe {
            if !self.scene.is_null() {
                sys::rtcReleaseScene(self.scene);
            }
            sys::rtcReleaseDevice(self.device);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    fn quad() -> [Triangle; 2] {
        let p = |x: f32, z: f32| Vec3::new(x, 0.0, z);
        [
            Triangle::new(p(-1.0, -1.0), p(-1.0, 1.0), p(1.0, 1.0)),
            Triangle::new(p(-1.0, -1.0), p(1.0, 1.0), p(1.0, -1.0)),
        ]
    }

    #[test]
    fn hits_report_the_callers_indices_and_skip_non_finite_triangles() {
        let mut triangles = vec![Triangle::new(Vec3::NAN, Vec3::X, Vec3::Y)];
        triangles.extend(quad());
        let embree = EmbreeIntersector::build(&triangles).unwrap();
        assert_eq!(embree.triangle_count(), 2);
        let hit = embree.intersect(&Ray::new(Vec3::new(0.5, 1.0, 0.2), Vec3::NEG_Y)).unwrap();
        assert_eq!(hit.primitive, 2);
        assert!((hit.t - 1.0).abs() < 1e-6);
        let p = (1.0 - hit.barycentrics.x - hit.barycentrics.y) * triangles[2].vertices[0]
            + hit.barycentrics.x * triangles[2].vertices[1]
            + hit.barycentrics.y * triangles[2].vertices[2];
        assert!(p.distance(Vec3::new(0.5, 0.0, 0.2)) < 1e-6, "{p}");
        assert!(embree.take_errors().is_empty());
    }

    #[test]
    fn segments_exclude_their_end_points_and_bad_rays_miss() {
        let embree = EmbreeIntersector::build(&quad()).unwrap();
        let down = |t_max| Ray::segment(Vec3::new(0.1, 1.0, 0.1), Vec3::NEG_Y, 0.0, t_max);
        assert!(embree.occluded(&down(1.5)));
        // Embree's t is accurate to a few ulps, so a segment stopping a hair short of the
        // surface is not blocked by it.
        assert!(!embree.occluded(&down(1.0 - 1e-6)), "a shadow ray ending on the surface is not blocked by it");
        assert!(!embree.occluded(&down(0.5)));
        assert!(embree.intersect(&Ray::new(Vec3::NAN, Vec3::NEG_Y)).is_none());
        assert!(embree.intersect(&Ray::new(Vec3::Y, Vec3::ZERO)).is_none());
        assert!(!embree.occluded(&Ray::segment(Vec3::Y, Vec3::NEG_Y, 2.0, 1.0)));
    }

    /// Packets answer as single rays do, to the bit: full and partial packets, rays that
    /// miss, untraceable rays and segments that stop short.
    #[test]
    fn packets_answer_as_single_rays() {
        // A crumpled sheet of triangles, with a NaN one so indices need remapping.
        let mut triangles = vec![Triangle::new(Vec3::NAN, Vec3::X, Vec3::Y)];
        let height = |x: f32, z: f32| (3.0 * x).sin() * (2.0 * z).cos() * 0.3;
        let n = 12;
        for i in 0..n {
            for j in 0..n {
                let p = |a: usize, b: usize| {
                    let (x, z) = (a as f32 / n as f32 * 2.0 - 1.0, b as f32 / n as f32 * 2.0 - 1.0);
                    Vec3::new(x, height(x, z), z)
                };
                triangles.push(Triangle::new(p(i, j), p(i, j + 1), p(i + 1, j + 1)));
                triangles.push(Triangle::new(p(i, j), p(i + 1, j + 1), p(i + 1, j)));
            }
        }
        let embree = EmbreeIntersector::build(&triangles).unwrap();
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 40) as f32 / (1u64 << 24) as f32
        };
        let mut rays: Vec<Ray> = (0..53)
            .map(|_| {
                let origin = Vec3::new(next() * 2.0 - 1.0, 0.6 + 0.4 * next(), next() * 2.0 - 1.0);
                let direction = Vec3::new(next() - 0.5, -0.3 - next(), next() - 0.5).normalize();
                Ray::segment(origin, direction, 0.0, 0.8 + 2.0 * next())
            })
            .collect();
        rays[7] = Ray::new(Vec3::NAN, Vec3::NEG_Y);
        rays[20] = Ray::new(Vec3::Y, Vec3::ZERO);
        rays[33] = Ray::new(Vec3::new(0.0, 2.0, 0.0), Vec3::Y);
        for count in [rays.len(), 16, 5] {
            let rays = &rays[..count];
            let mut hits = vec![None; count];
            let mut blocked = vec![true; count];
            embree.intersect_many(rays, &mut hits);
            embree.occluded_many(rays, &mut blocked);
            for (k, ray) in rays.iter().enumerate() {
                assert_eq!(hits[k], embree.intersect(ray), "ray {k} of {count}");
                assert_eq!(blocked[k], embree.occluded(ray), "ray {k} of {count}");
            }
            assert!(hits.iter().filter(|h| h.is_some()).count() > count / 3, "most rays hit the sheet");
            assert!(hits[..5].iter().flatten().all(|h| h.primitive >= 1), "indices are the caller's");
        }
        let empty = EmbreeIntersector::build(&[]).unwrap();
        let mut hits = vec![Some(Hit { t: 1.0, primitive: 0, barycentrics: Vec2::ZERO }); 3];
        empty.intersect_many(&rays[..3], &mut hits);
        assert_eq!(hits, vec![None; 3]);
    }

    #[test]
    fn an_empty_scene_builds_and_misses() {
        let embree = EmbreeIntersector::build(&[]).unwrap();
        assert!(embree.intersect(&Ray::new(Vec3::Y, Vec3::NEG_Y)).is_none());
        assert!(!embree.occluded(&Ray::new(Vec3::Y, Vec3::NEG_Y)));
    }
}

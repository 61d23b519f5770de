//! The part of Embree's C API the caster calls, opened at run time with libloading.
//!
//! Embree 3 (Debian's `libembree3-3`) and Embree 4 (the library inside PyPI's
//! `embreex` wheel, or any build of 4.x) are both accepted. The two versions share
//! every call used here except the ray queries, whose last two pointer arguments swap
//! places: Embree 3 takes `(scene, context, ray)`, Embree 4 `(scene, ray, arguments)`.
//! [`Library::query`] hides that, and the small context/arguments block each version
//! wants is built by [`QueryArgs`].
//!
//! Which library: the file that `WARPRAY_EMBREE` names, else `libembree4.so.4`, else
//! `libembree3.so.3`, found by the system's loader.

use crate::error::{Error, Result};
use std::ffi::{c_char, c_int, c_uint, c_void};
use std::path::PathBuf;
use std::sync::OnceLock;

/// The environment variable that names the Embree library to open.
pub const LIBRARY_ENV: &str = "WARPRAY_EMBREE";

pub(crate) type Handle = *mut c_void;

type NewDeviceFn = unsafe extern "C" fn(*const c_char) -> Handle;
type ReleaseFn = unsafe extern "C" fn(Handle);
type DevicePropertyFn = unsafe extern "C" fn(Handle, c_int) -> isize;
type DeviceErrorFn = unsafe extern "C" fn(Handle) -> c_int;
pub(crate) type MemoryMonitorFn = unsafe extern "C" fn(*mut c_void, isize, bool) -> bool;
type SetMemoryMonitorFn = unsafe extern "C" fn(Handle, Option<MemoryMonitorFn>, *mut c_void);
type NewSceneFn = unsafe extern "C" fn(Handle) -> Handle;
type SetIntFn = unsafe extern "C" fn(Handle, c_int);
type NewGeometryFn = unsafe extern "C" fn(Handle, c_int) -> Handle;
type NewBufferFn = unsafe extern "C" fn(Handle, c_int, c_uint, c_int, usize, usize) -> *mut c_void;
type UpdateBufferFn = unsafe extern "C" fn(Handle, c_int, c_uint);
type AttachFn = unsafe extern "C" fn(Handle, Handle) -> c_uint;
/// `rtcIntersect1`/`rtcOccluded1`: three pointers, in the version's order.
type Query1Fn = unsafe extern "C" fn(Handle, *mut c_void, *mut c_void);
/// `rtcIntersect16`/`rtcOccluded16`: the valid mask, then as [`Query1Fn`].
type Query16Fn = unsafe extern "C" fn(*const i32, Handle, *mut c_void, *mut c_void);

// Enumerations, equal in Embree 3 and 4.
pub(crate) const GEOMETRY_TYPE_TRIANGLE: c_int = 0;
pub(crate) const BUFFER_TYPE_INDEX: c_int = 0;
pub(crate) const BUFFER_TYPE_VERTEX: c_int = 1;
pub(crate) const FORMAT_UINT3: c_int = 0x5003;
pub(crate) const FORMAT_FLOAT3: c_int = 0x9003;
pub(crate) const SCENE_FLAG_DYNAMIC: c_int = 1;
pub(crate) const SCENE_FLAG_ROBUST: c_int = 1 << 2;
pub(crate) const BUILD_QUALITY_REFIT: c_int = 3;
const DEVICE_PROPERTY_VERSION: c_int = 0;
/// `geomID` of a ray that hit nothing.
pub(crate) const INVALID_ID: u32 = u32::MAX;

/// One ray and its hit, laid out as `RTCRayHit`. The hit is followed by room for the
/// fields some Embree 4 builds add (`instPrimID`), so either version may write them.
#[repr(C, align(16))]
#[derive(Clone, Copy)]
pub(crate) struct RayHit1 {
    pub org: [f32; 3],
    pub tnear: f32,
    pub dir: [f32; 3],
    pub time: f32,
    pub tfar: f32,
    pub mask: u32,
    pub id: u32,
    pub flags: u32,
    pub ng: [f32; 3],
    pub u: f32,
    pub v: f32,
    pub prim_id: u32,
    pub geom_id: u32,
    pub inst_id: u32,
    _room: [u32; 4],
}

impl RayHit1 {
    pub fn new(org: [f32; 3], dir: [f32; 3], tnear: f32, tfar: f32) -> Self {
        RayHit1 {
            org,
            tnear,
            dir,
            time: 0.0,
            tfar,
            mask: u32::MAX,
            id: 0,
            flags: 0,
            ng: [0.0; 3],
            u: 0.0,
            v: 0.0,
            prim_id: INVALID_ID,
            geom_id: INVALID_ID,
            inst_id: INVALID_ID,
            _room: [INVALID_ID; 4],
        }
    }
}

/// The valid mask of a 16-ray packet: -1 for each lane to trace, 0 for the others.
/// Embree reads it with an aligned 64-byte load, so it is 64-byte aligned (a plain
/// `[i32; 16]` is only 4-byte aligned, and crashed where the compiler placed it so).
#[repr(C, align(64))]
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Valid16(pub [i32; 16]);

/// Sixteen rays and hits in SoA layout (`RTCRayHit16`), 64-byte aligned, with room
/// after the hit as in [`RayHit1`].
#[repr(C, align(64))]
pub(crate) struct RayHit16 {
    pub org: [[f32; 16]; 3],
    pub tnear: [f32; 16],
    pub dir: [[f32; 16]; 3],
    pub time: [f32; 16],
    pub tfar: [f32; 16],
    pub mask: [u32; 16],
    pub id: [u32; 16],
    pub flags: [u32; 16],
    pub ng: [[f32; 16]; 3],
    pub u: [f32; 16],
    pub v: [f32; 16],
    pub prim_id: [u32; 16],
    pub geom_id: [u32; 16],
    pub inst_id: [u32; 16],
    _room: [[u32; 16]; 4],
}

impl RayHit16 {
    /// A packet with every lane off (`valid` all 0) and no hits.
    pub fn empty() -> Self {
        RayHit16 {
            org: [[0.0; 16]; 3],
            tnear: [0.0; 16],
            dir: [[1.0; 16]; 3],
            time: [0.0; 16],
            tfar: [0.0; 16],
            mask: [u32::MAX; 16],
            id: [0; 16],
            flags: [0; 16],
            ng: [[0.0; 16]; 3],
            u: [0.0; 16],
            v: [0.0; 16],
            prim_id: [INVALID_ID; 16],
            geom_id: [INVALID_ID; 16],
            inst_id: [INVALID_ID; 16],
            _room: [[INVALID_ID; 16]; 4],
        }
    }

    /// Sets lane `i` to a ray.
    pub fn set(&mut self, i: usize, org: [f32; 3], dir: [f32; 3], tnear: f32, tfar: f32) {
        for k in 0..3 {
            self.org[k][i] = org[k];
            self.dir[k][i] = dir[k];
        }
        self.tnear[i] = tnear;
        self.tfar[i] = tfar;
        self.geom_id[i] = INVALID_ID;
        self.prim_id[i] = INVALID_ID;
    }
}

/// The block a query takes beside the ray: Embree 3's `RTCIntersectContext` or Embree
/// 4's `RTCIntersectArguments`/`RTCOccludedArguments`, zero-padded so that builds with
/// optional trailing fields read zeros.
#[repr(C, align(16))]
pub(crate) struct QueryArgs([u8; 64]);

impl QueryArgs {
    fn new(major: u32, coherent: bool) -> Self {
        let mut b = [0u8; 64];
        // Both versions: `flags` first, 1 = coherent, 0 = incoherent.
        b[0..4].copy_from_slice(&(coherent as u32).to_ne_bytes());
        if major >= 4 {
            // `feature_mask`: every feature (RTC_FEATURE_FLAG_ALL); then null context,
            // filter and intersect callbacks.
            b[4..8].copy_from_slice(&u32::MAX.to_ne_bytes());
        } else {
            // `filter` null at 8; `instID[0]` = RTC_INVALID_GEOMETRY_ID at 16.
            b[16..20].copy_from_slice(&INVALID_ID.to_ne_bytes());
        }
        QueryArgs(b)
    }
}

/// Which query: closest hit or occlusion.
#[derive(Clone, Copy, PartialEq, Eq)]
pub(crate) enum Query {
    Intersect,
    Occluded,
}

/// The opened library and its entry points.
pub(crate) struct Library {
    pub path: PathBuf,
    /// Major version of the library (3 or 4).
    pub major: u32,
    /// Its whole version, as Embree writes it (40400 for 4.4.0).
    pub version: u32,
    new_device: NewDeviceFn,
    release_device: ReleaseFn,
    device_error: DeviceErrorFn,
    set_memory_monitor: SetMemoryMonitorFn,
    new_scene: NewSceneFn,
    set_scene_flags: SetIntFn,
    set_scene_quality: SetIntFn,
    commit_scene: ReleaseFn,
    release_scene: ReleaseFn,
    new_geometry: NewGeometryFn,
    set_geometry_quality: SetIntFn,
    new_buffer: NewBufferFn,
    update_buffer: UpdateBufferFn,
    commit_geometry: ReleaseFn,
    attach: AttachFn,
    release_geometry: ReleaseFn,
    intersect1: Query1Fn,
    occluded1: Query1Fn,
    intersect16: Query16Fn,
    occluded16: Query16Fn,
    // Last: the entry points above must not outlive it.
    _lib: libloading::Library,
}

/// The library, opened once per process.
pub(crate) fn library() -> Result<&'static Library> {
    static LIB: OnceLock<std::result::Result<Library, (PathBuf, String)>> = OnceLock::new();
    LIB.get_or_init(Library::open_default)
        .as_ref()
        .map_err(|(library, msg)| Error::Embree { library: library.clone(), msg: msg.clone() })
}

impl Library {
    fn open_default() -> std::result::Result<Library, (PathBuf, String)> {
        if let Some(p) = std::env::var_os(LIBRARY_ENV) {
            return Library::open(PathBuf::from(p));
        }
        let first = Library::open(PathBuf::from("libembree4.so.4"));
        first.or_else(|(_, e4)| {
            Library::open(PathBuf::from("libembree3.so.3")).map_err(|(p, e3)| {
                let msg = format!(
                    "no Embree library found ({e4}; {e3}); install Debian's libembree3-3 \
                     (`apt-get install libembree-dev`) or point {LIBRARY_ENV} at libembree4.so.4"
                );
                (p, msg)
            })
        })
    }

    fn open(path: PathBuf) -> std::result::Result<Library, (PathBuf, String)> {
        let fail = |msg: String| (path.clone(), msg);
        // SAFETY: loading runs Embree's initialisers (its TBB runtime), nothing of ours.
        let lib = unsafe { libloading::Library::new(&path) }.map_err(|e| fail(format!("cannot open: {e}")))?;
        macro_rules! sym {
            ($name:literal, $ty:ty) => {
                // SAFETY: the symbol has this signature in Embree 3's and 4's headers (the
                // queries' pointer order is handled by `Library::query`).
                *unsafe { lib.get::<$ty>($name) }.map_err(|e| fail(format!("missing symbol: {e}")))?
            };
        }
        let new_device = sym!(b"rtcNewDevice\0", NewDeviceFn);
        let release_device = sym!(b"rtcReleaseDevice\0", ReleaseFn);
        let property = sym!(b"rtcGetDeviceProperty\0", DevicePropertyFn);
        // SAFETY: an empty configuration string; the device is released below.
        let device = unsafe { new_device(c"".as_ptr()) };
        if device.is_null() {
            return Err(fail("rtcNewDevice failed (unsupported CPU?)".into()));
        }
        // SAFETY: a live device and a property both versions define.
        let version = unsafe { property(device, DEVICE_PROPERTY_VERSION) } as u32;
        // SAFETY: released once.
        unsafe { release_device(device) };
        let major = version / 10_000;
        if !(3..=4).contains(&major) {
            return Err(fail(format!("Embree version {version}: this build speaks Embree 3 and 4")));
        }
        Ok(Library {
            major,
            version,
            new_device,
            release_device,
            device_error: sym!(b"rtcGetDeviceError\0", DeviceErrorFn),
            set_memory_monitor: sym!(b"rtcSetDeviceMemoryMonitorFunction\0", SetMemoryMonitorFn),
            new_scene: sym!(b"rtcNewScene\0", NewSceneFn),
            set_scene_flags: sym!(b"rtcSetSceneFlags\0", SetIntFn),
            set_scene_quality: sym!(b"rtcSetSceneBuildQuality\0", SetIntFn),
            commit_scene: sym!(b"rtcCommitScene\0", ReleaseFn),
            release_scene: sym!(b"rtcReleaseScene\0", ReleaseFn),
            new_geometry: sym!(b"rtcNewGeometry\0", NewGeometryFn),
            set_geometry_quality: sym!(b"rtcSetGeometryBuildQuality\0", SetIntFn),
            new_buffer: sym!(b"rtcSetNewGeometryBuffer\0", NewBufferFn),
            update_buffer: sym!(b"rtcUpdateGeometryBuffer\0", UpdateBufferFn),
            commit_geometry: sym!(b"rtcCommitGeometry\0", ReleaseFn),
            attach: sym!(b"rtcAttachGeometry\0", AttachFn),
            release_geometry: sym!(b"rtcReleaseGeometry\0", ReleaseFn),
            intersect1: sym!(b"rtcIntersect1\0", Query1Fn),
            occluded1: sym!(b"rtcOccluded1\0", Query1Fn),
            intersect16: sym!(b"rtcIntersect16\0", Query16Fn),
            occluded16: sym!(b"rtcOccluded16\0", Query16Fn),
            path,
            _lib: lib,
        })
    }

    /// The query block for this library's version.
    pub fn args(&self, coherent: bool) -> QueryArgs {
        QueryArgs::new(self.major, coherent)
    }

    /// `rtcIntersect1` or `rtcOccluded1` on one ray.
    ///
    /// # Safety
    /// `scene` is a committed scene of this library.
    pub unsafe fn query1(&self, q: Query, scene: Handle, ray: &mut RayHit1, args: &mut QueryArgs) {
        let f = if q == Query::Intersect { self.intersect1 } else { self.occluded1 };
        let (r, a) = (ray as *mut RayHit1 as *mut c_void, args as *mut QueryArgs as *mut c_void);
        // SAFETY: the caller's scene; `RayHit1` starts with `RTCRay` and has room for
        // any `RTCHit`; the argument block is zero-padded.
        unsafe { if self.major >= 4 { f(scene, r, a) } else { f(scene, a, r) } }
    }

    /// `rtcIntersect16` or `rtcOccluded16` on a packet; `valid` is -1 for lanes to trace.
    ///
    /// # Safety
    /// As [`Library::query1`].
    pub unsafe fn query16(&self, q: Query, valid: &Valid16, scene: Handle, rays: &mut RayHit16, args: &mut QueryArgs) {
        let f = if q == Query::Intersect { self.intersect16 } else { self.occluded16 };
        let (r, a) = (rays as *mut RayHit16 as *mut c_void, args as *mut QueryArgs as *mut c_void);
        // SAFETY: as in `query1`; the packet and the mask are 64-byte aligned as Embree
        // requires (it loads both with aligned vector loads).
        let v = valid.0.as_ptr();
        unsafe { if self.major >= 4 { f(v, scene, r, a) } else { f(v, scene, a, r) } }
    }

    /// The device's pending error, as text (`None` when there is none).
    pub fn error(&self, device: Handle) -> Option<String> {
        // SAFETY: a live device.
        let code = unsafe { (self.device_error)(device) };
        let name = match code {
            0 => return None,
            1 => "unknown error",
            2 => "invalid argument",
            3 => "invalid operation",
            4 => "out of memory",
            5 => "unsupported CPU",
            6 => "cancelled",
            _ => "error",
        };
        Some(format!("{name} (code {code})"))
    }
}

/// Thin, unsafe wrappers: each is the C call of the same name.
#[allow(clippy::missing_safety_doc)]
impl Library {
    pub unsafe fn new_device(&self, config: &std::ffi::CStr) -> Handle {
        unsafe { (self.new_device)(config.as_ptr()) }
    }
    pub unsafe fn release_device(&self, d: Handle) {
        unsafe { (self.release_device)(d) }
    }
    pub unsafe fn set_memory_monitor(&self, d: Handle, f: MemoryMonitorFn, user: *mut c_void) {
        unsafe { (self.set_memory_monitor)(d, Some(f), user) }
    }
    pub unsafe fn new_scene(&self, d: Handle) -> Handle {
        unsafe { (self.new_scene)(d) }
    }
    pub unsafe fn set_scene_flags(&self, s: Handle, flags: c_int) {
        unsafe { (self.set_scene_flags)(s, flags) }
    }
    pub unsafe fn set_scene_quality(&self, s: Handle, q: c_int) {
        unsafe { (self.set_scene_quality)(s, q) }
    }
    pub unsafe fn commit_scene(&self, s: Handle) {
        unsafe { (self.commit_scene)(s) }
    }
    pub unsafe fn release_scene(&self, s: Handle) {
        unsafe { (self.release_scene)(s) }
    }
    pub unsafe fn new_geometry(&self, d: Handle) -> Handle {
        unsafe { (self.new_geometry)(d, GEOMETRY_TYPE_TRIANGLE) }
    }
    pub unsafe fn set_geometry_quality(&self, g: Handle, q: c_int) {
        unsafe { (self.set_geometry_quality)(g, q) }
    }
    pub unsafe fn new_buffer(&self, g: Handle, kind: c_int, format: c_int, stride: usize, n: usize) -> *mut c_void {
        unsafe { (self.new_buffer)(g, kind, 0, format, stride, n) }
    }
    pub unsafe fn update_buffer(&self, g: Handle, kind: c_int) {
        unsafe { (self.update_buffer)(g, kind, 0) }
    }
    pub unsafe fn commit_geometry(&self, g: Handle) {
        unsafe { (self.commit_geometry)(g) }
    }
    pub unsafe fn attach(&self, s: Handle, g: Handle) -> c_uint {
        unsafe { (self.attach)(s, g) }
    }
    pub unsafe fn release_geometry(&self, g: Handle) {
        unsafe { (self.release_geometry)(g) }
    }
}

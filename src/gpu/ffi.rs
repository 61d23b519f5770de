//! The C interface of `libwarpray_cuda` (`cuda/pdacrt_api.h`, `cuda/bvh_api.h` for the
//! GPU BVH baseline, and `cuda/cis_api.h` for CIS-LBDPT's twins), opened with libloading.

use crate::error::{Error, Result};
use crate::geometry::{Aabb, Ray};
use std::ffi::{CStr, c_char, c_int, c_void};
use std::path::PathBuf;

/// Environment variable naming the CUDA library (default [`DEFAULT_LIBRARY`]).
pub const LIBRARY_ENV: &str = "WARPRAY_CUDA_LIB";
/// Where `cuda/build.sh` puts the library, relative to the repository root.
pub const DEFAULT_LIBRARY: &str = "target/cuda/libwarpray_cuda.so";

/// The library path: `$WARPRAY_CUDA_LIB`, else [`DEFAULT_LIBRARY`].
pub fn library_path() -> PathBuf {
    std::env::var_os(LIBRARY_ENV).map(PathBuf::from).unwrap_or_else(|| PathBuf::from(DEFAULT_LIBRARY))
}

/// `WR_API_VERSION` of the header this file mirrors.
const API_VERSION: c_int = 7;

#[repr(C)]
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct WrParams {
    pub leaf_rays: u32,
    pub leaf_triangles: u32,
    pub max_depth: u32,
    pub brute_force_block: u32,
    pub leaf_pairs: u64,
    pub chunk_rays: u64,
    pub slab_widen: f32,
    /// `geometry::batch_slack` of the call's rays: how far `filter_rays` grows boxes.
    pub grow: f32,
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct WrStats {
    pub trace_ms: f64,
    pub call_ms: f64,
    pub tests: u64,
    pub levels: u32,
    pub launches: u32,
    pub peak_bytes: u64,
    pub read_backs: u32,
    pub reserved: u32,
}

/// What the GPU BVH's most recent build or trace did (`GpuBvhStats` of
/// `cuda/bvh_api.h`); a call fills the fields it names.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct GpuBvhStats {
    /// Build: host-to-device copy of the triangles (host wall time), milliseconds.
    pub upload_ms: f64,
    /// Build: GPU time of the build with the triangles resident (CUDA events).
    pub build_ms: f64,
    /// Trace: GPU time of the traversal with the rays resident (CUDA events).
    pub trace_ms: f64,
    /// Host wall time of the call, transfers included.
    pub call_ms: f64,
    /// Trace: ray–triangle tests.
    pub tests: u64,
    /// Trace: inner nodes visited (each one fetch of 64 bytes and two box tests).
    pub visits: u64,
    /// Build: inner nodes (triangles − 1; one triangle per leaf).
    pub nodes: u64,
    /// Build: device bytes of the structure (nodes, reordered triangles, their ids).
    pub bytes: u64,
}

type VersionFn = unsafe extern "C" fn() -> c_int;
type DeviceNameFn = unsafe extern "C" fn(*mut c_char, u32) -> c_int;
type CreateFn = unsafe extern "C" fn(*const f32, u64, *const f32, *mut *mut c_void) -> c_int;
type SetTrianglesFn = unsafe extern "C" fn(*mut c_void, *const f32, u64, *const f32) -> c_int;
type TraceFn =
    unsafe extern "C" fn(*mut c_void, *const c_void, u64, c_int, *const WrParams, *mut u64, *mut WrStats) -> c_int;
type DestroyFn = unsafe extern "C" fn(*mut c_void);
type ErrorFn = unsafe extern "C" fn() -> *const c_char;
type BvhCreateFn = unsafe extern "C" fn(*mut *mut c_void) -> c_int;
type BvhBuildFn = unsafe extern "C" fn(*mut c_void, *const f32, u64, *mut GpuBvhStats) -> c_int;
type BvhTraceFn =
    unsafe extern "C" fn(*mut c_void, *const c_void, u64, c_int, f32, f32, *mut u64, *mut GpuBvhStats) -> c_int;
type CisCreateFn = unsafe extern "C" fn(*const c_void, *mut *mut c_void) -> c_int;
type CisShadeFn = unsafe extern "C" fn(
    *mut c_void,
    c_int,
    u64,
    *const u32,
    *const u32,
    *const c_void,
    u64,
    *mut c_void,
    *mut c_void,
    *mut c_void,
    *mut f64,
) -> c_int;
type CisCompactFn =
    unsafe extern "C" fn(*mut c_void, u64, *const u32, u64, *const c_void, *mut u32, *mut u64, *mut f64) -> c_int;

/// The GPU BVH's entry points (`cuda/bvh_api.h`).
type RenderCreateFn = unsafe extern "C" fn(*const c_void, *const c_void, *mut *mut c_void, *mut c_void) -> c_int;
type RenderPassFn = unsafe extern "C" fn(*mut c_void, u32, *mut f32, *mut *const f32, *mut u64, *mut c_void) -> c_int;

pub(crate) struct RenderFns {
    pub create: RenderCreateFn,
    pub pass: RenderPassFn,
    pub destroy: DestroyFn,
    pub last_error: ErrorFn,
}

struct BvhFns {
    create: BvhCreateFn,
    build: BvhBuildFn,
    trace: BvhTraceFn,
    destroy: DestroyFn,
    last_error: ErrorFn,
}

/// CIS-LBDPT's entry points (`cuda/cis_api.h`).
pub(crate) struct CisFns {
    pub create: CisCreateFn,
    pub shade: CisShadeFn,
    pub compact: CisCompactFn,
    pub destroy: DestroyFn,
    pub last_error: ErrorFn,
}

/// The opened library and its entry points.
pub(crate) struct Library {
    path: PathBuf,
    device_name: DeviceNameFn,
    create: CreateFn,
    set_triangles: SetTrianglesFn,
    trace: TraceFn,
    destroy: DestroyFn,
    last_error: ErrorFn,
    bvh: BvhFns,
    pub(crate) cis: CisFns,
    pub(crate) render: RenderFns,
    // Last: the entry points above must not outlive it.
    _lib: libloading::Library,
}

/// A traced scene on the GPU; destroyed with the library's `wr_pdacrt_destroy`.
pub(crate) struct Handle {
    ptr: *mut c_void,
    destroy: DestroyFn,
}

// SAFETY: the handle is only used under the caster's mutex (one call at a time), and
// the CUDA runtime allows use of a context from any host thread.
unsafe impl Send for Handle {}

impl Drop for Handle {
    fn drop(&mut self) {
        // SAFETY: `ptr` came from `wr_pdacrt_create` and is dropped once.
        unsafe { (self.destroy)(self.ptr) }
    }
}

impl Library {
    pub fn open(path: PathBuf) -> Result<Library> {
        let err = |msg: String| Error::Gpu { library: path.clone(), msg };
        if !path.is_file() {
            return Err(err(format!(
                "not found; build it on a machine with CUDA with `sh cuda/build.sh`, or point {} at it",
                LIBRARY_ENV
            )));
        }
        // SAFETY: loading runs the library's initialisers; ours has none beyond the CUDA
        // runtime's static state.
        let lib = unsafe { libloading::Library::new(&path) }.map_err(|e| err(format!("cannot open: {e}")))?;
        macro_rules! sym {
            ($name:literal, $ty:ty) => {
                // SAFETY: the symbol has this signature in cuda/pdacrt_api.h, checked by
                // the API version below.
                *unsafe { lib.get::<$ty>($name) }.map_err(|e| err(format!("missing symbol: {e}")))?
            };
        }
        let version = sym!(b"wr_api_version\0", VersionFn);
        // SAFETY: no arguments, returns an int.
        let v = unsafe { version() };
        if v != API_VERSION {
            return Err(err(format!("API version {v}, this build of warpray speaks {API_VERSION}: rebuild it")));
        }
        Ok(Library {
            device_name: sym!(b"wr_device_name\0", DeviceNameFn),
            create: sym!(b"wr_pdacrt_create\0", CreateFn),
            set_triangles: sym!(b"wr_pdacrt_set_triangles\0", SetTrianglesFn),
            trace: sym!(b"wr_pdacrt_trace\0", TraceFn),
            destroy: sym!(b"wr_pdacrt_destroy\0", DestroyFn),
            last_error: sym!(b"wr_last_error\0", ErrorFn),
            bvh: BvhFns {
                create: sym!(b"wr_bvh_create\0", BvhCreateFn),
                build: sym!(b"wr_bvh_build\0", BvhBuildFn),
                trace: sym!(b"wr_bvh_trace\0", BvhTraceFn),
                destroy: sym!(b"wr_bvh_destroy\0", DestroyFn),
                last_error: sym!(b"wr_bvh_last_error\0", ErrorFn),
            },
            cis: CisFns {
                create: sym!(b"wr_cis_create\0", CisCreateFn),
                shade: sym!(b"wr_cis_shade\0", CisShadeFn),
                compact: sym!(b"wr_cis_compact\0", CisCompactFn),
                destroy: sym!(b"wr_cis_destroy\0", DestroyFn),
                last_error: sym!(b"wr_cis_last_error\0", ErrorFn),
            },
            render: RenderFns {
                create: sym!(b"wr_render_create\0", RenderCreateFn),
                pass: sym!(b"wr_render_pass\0", RenderPassFn),
                destroy: sym!(b"wr_render_destroy\0", DestroyFn),
                last_error: sym!(b"wr_render_last_error\0", ErrorFn),
            },
            path,
            _lib: lib,
        })
    }

    fn error(&self, what: &str) -> Error {
        self.error_from(self.last_error, what)
    }

    /// The error `last_error` reports (PDACRT's or CIS's), for the failed step `what`.
    pub(crate) fn error_from(&self, last_error: ErrorFn, what: &str) -> Error {
        // SAFETY: returns a NUL-terminated string owned by the library (thread-local).
        let msg = unsafe { CStr::from_ptr(last_error()) }.to_string_lossy().into_owned();
        Error::Gpu { library: self.path.clone(), msg: format!("{what}: {msg}") }
    }

    pub fn device_name(&self) -> Result<String> {
        let mut buf = [0 as c_char; 256];
        // SAFETY: the buffer and its length.
        if unsafe { (self.device_name)(buf.as_mut_ptr(), buf.len() as u32) } != 0 {
            return Err(self.error("no CUDA device"));
        }
        // SAFETY: the library wrote a NUL-terminated string into it.
        Ok(unsafe { CStr::from_ptr(buf.as_ptr()) }.to_string_lossy().into_owned())
    }

    pub fn create(&self, tris: &[[f32; 9]], scene_box: Aabb) -> Result<Handle> {
        let b = [scene_box.min.x, scene_box.min.y, scene_box.min.z, scene_box.max.x, scene_box.max.y, scene_box.max.z];
        let mut ptr = std::ptr::null_mut();
        // SAFETY: `tris` holds `len` records of 9 floats; `b` six floats.
        let rc = unsafe { (self.create)(tris.as_ptr().cast(), tris.len() as u64, b.as_ptr(), &mut ptr) };
        if rc != 0 {
            return Err(self.error("uploading the triangles"));
        }
        Ok(Handle { ptr, destroy: self.destroy })
    }

    /// Replaces the triangles of `h`, keeping its working buffers.
    pub fn set_triangles(&self, h: &Handle, tris: &[[f32; 9]], scene_box: Aabb) -> Result<()> {
        let b = [scene_box.min.x, scene_box.min.y, scene_box.min.z, scene_box.max.x, scene_box.max.y, scene_box.max.z];
        // SAFETY: as `create`; the handle came from `create`.
        let rc = unsafe { (self.set_triangles)(h.ptr, tris.as_ptr().cast(), tris.len() as u64, b.as_ptr()) };
        if rc != 0 {
            return Err(self.error("uploading the triangles"));
        }
        Ok(())
    }

    pub fn trace(&self, h: &Handle, rays: &[Ray], any_hit: bool, p: &WrParams, keys: &mut [u64]) -> Result<WrStats> {
        assert_eq!(rays.len(), keys.len());
        let mut stats = WrStats::default();
        // SAFETY: `Ray` is #[repr(C)] with the header's 32-byte layout; `keys` has one
        // slot per ray; the handle is live.
        let rc = unsafe {
            (self.trace)(
                h.ptr,
                rays.as_ptr().cast(),
                rays.len() as u64,
                any_hit as c_int,
                p,
                keys.as_mut_ptr(),
                &mut stats,
            )
        };
        if rc != 0 {
            return Err(self.error("tracing"));
        }
        Ok(stats)
    }

    /// An empty GPU BVH.
    pub fn bvh_create(&self) -> Result<Handle> {
        let mut ptr = std::ptr::null_mut();
        // SAFETY: writes one pointer.
        if unsafe { (self.bvh.create)(&mut ptr) } != 0 {
            return Err(self.error_from(self.bvh.last_error, "creating the GPU BVH"));
        }
        Ok(Handle { ptr, destroy: self.bvh.destroy })
    }

    /// Uploads `tris` and rebuilds the BVH over them.
    pub fn bvh_build(&self, h: &Handle, tris: &[[f32; 9]]) -> Result<GpuBvhStats> {
        let mut stats = GpuBvhStats::default();
        // SAFETY: `tris` holds `len` records of 9 floats; the handle came from `bvh_create`.
        let rc = unsafe { (self.bvh.build)(h.ptr, tris.as_ptr().cast(), tris.len() as u64, &mut stats) };
        if rc != 0 {
            return Err(self.error_from(self.bvh.last_error, "building the GPU BVH"));
        }
        Ok(stats)
    }

    /// Traces `rays` through the BVH: one key per ray, as [`Library::trace`]; node
    /// boxes grown by `grow` (`geometry::batch_slack`).
    pub fn bvh_trace(
        &self,
        h: &Handle,
        rays: &[Ray],
        any_hit: bool,
        grow: f32,
        keys: &mut [u64],
    ) -> Result<GpuBvhStats> {
        assert_eq!(rays.len(), keys.len());
        let mut stats = GpuBvhStats::default();
        // SAFETY: as `trace`; the handle came from `bvh_create`.
        let rc = unsafe {
            (self.bvh.trace)(
                h.ptr,
                rays.as_ptr().cast(),
                rays.len() as u64,
                any_hit as c_int,
                crate::geometry::SLAB_WIDEN,
                grow,
                keys.as_mut_ptr(),
                &mut stats,
            )
        };
        if rc != 0 {
            return Err(self.error_from(self.bvh.last_error, "tracing the GPU BVH"));
        }
        Ok(stats)
    }
}

const _: () = assert!(std::mem::size_of::<Ray>() == 32);
const _: () = assert!(std::mem::size_of::<WrParams>() == 40);
const _: () = assert!(std::mem::size_of::<WrStats>() == 48);
const _: () = assert!(std::mem::size_of::<GpuBvhStats>() == 64);

//! Instruction weights of the arithmetic that `simt` kernels share with host code (the
//! BSDFs, sampling, MIS weights and connections that CIS-LBDPT's `cis::shade` runs), for
//! the emulator's SIMD model. Shared functions declare them with [`declare!`] (and mark
//! inlined calls and loops with [`scope`]); inside a kernel's
//! [`simt::Thread::ambient`] call they count as that lane's instructions, anywhere else
//! they do nothing.
//!
//! Both compile to nothing without the cargo feature `model-arithmetic` (which `cuda`
//! turns on): even a check that finds no kernel running, at every declaration, cost the
//! CPU integrators about a quarter of their time (BDPT on the materials scene, 256²,
//! 8 spp: 2.64-2.79 s without, 3.48-3.76 s with; the development VM).
//!
//! **The rule** (`docs/gpu-check.md`, "The shading kernel's arithmetic"): one
//! instruction per scalar f32 add, subtract, multiply, compare, min, max, abs or select
//! (the twin is compiled with `-fmad=false`, so no multiply fuses with an add); for the
//! operations that compile to sequences on sm_90 with `-prec-div=true -prec-sqrt=true`,
//! the length of their common path as nvcc 13.0 emits it for sm_90: a division is 10
//! instructions (the convergence barrier, `MUFU.RCP`, `FCHK`, five `FFMA`, the branch
//! around the slow path, the barrier's end), a square root 10 (`MUFU.RSQ`, a range check
//! and its branch, four refinements, the barrier), `expf` 10 (a range reduction and
//! `MUFU.EX2`), `sinf` 26 and `cosf` 27, one weight of 27 for both (a Cody–Waite
//! reduction, the large-argument test and its branch, the polynomial with its selects).
//! This module's test derives these from the stored SASS of `cuda/probe_costs.cu`
//! (`docs/measured/probe-costs-sm90.sass`; `sh cuda/probe_costs.sh` prints it again). Vector operations are three scalar ones. The weights
//! are counted from the Rust source, not fitted to any measurement: the GPU's counts of
//! the same launches judge them.

/// A compare and its branch (or a select).
pub const BRANCH: u32 = 2;
/// f32 division (IEEE).
pub const DIV: u32 = 10;
/// f32 square root (IEEE).
pub const SQRT: u32 = 10;
/// `expf`.
pub const EXP: u32 = 10;
/// `sinf` or `cosf` (the longer, `cosf`'s).
pub const SIN_COS: u32 = 27;
/// Both of `sampling::sin_cos_quarter`'s polynomials on [−π/4, π/4]: the square and
/// their multiplies and adds.
pub const SIN_COS_QUARTER: u32 = 17;
/// A component-wise `Vec3` add, subtract or multiply.
pub const V3: u32 = 3;
/// `Vec3 / f32`: three divisions.
pub const V3_DIV: u32 = 3 * DIV;
/// Dot product: three multiplies, two adds.
pub const DOT: u32 = 5;
/// Cross product.
pub const CROSS: u32 = 9;
/// `normalize`: the length's reciprocal, three multiplies.
pub const NORMALIZE: u32 = DOT + SQRT + DIV + 3;
/// `normalize_or_zero`: the same and a finiteness test.
pub const NORMALIZE_OR_ZERO: u32 = NORMALIZE + 4;
/// A shading frame from a normal (Duff et al. 2017).
pub const FRAME: u32 = DIV + 16;
/// A direction into or out of a frame: three dot products, or three scaled adds.
pub const TO_LOCAL: u32 = 3 * DOT;
/// The reverse of [`TO_LOCAL`].
pub const TO_WORLD: u32 = 15;
/// One uniform number of [`crate::sampling::Rng`]: the 64-bit counter step and
/// `mix64` (64-bit multiplies are several 32-bit ones), then the conversion.
pub const RNG: u32 = 26;
/// Copying a path vertex (15 words) into a vertex list in local memory.
pub const VERTEX_COPY: u32 = 16;
/// Luminance of a colour.
pub const LUMINANCE: u32 = 5;

/// Declares `units` instructions of arithmetic here ([`simt::declare!`]) with the
/// feature `model-arithmetic`, in the region of its part of the code: the [`Part`] the
/// calling module names as its `COST_PART` (a module that declares work and names none
/// does not compile); nothing without the feature. `declare!(units, reads(record, words))` also records the
/// `words` 4-byte loads with which compiled code reads the fields it uses of `record`,
/// a reference into the scene ([`simt::read_words!`]).
#[cfg(feature = "model-arithmetic")]
macro_rules! declare {
    ($units:expr) => {
        simt::declare!($units, part { const PART: usize = COST_PART.index(); PART })
    };
    ($units:expr, reads($record:expr, $words:expr)) => {{
        simt::declare!($units, part { const PART: usize = COST_PART.index(); PART });
        simt::read_words!($record, $words)
    }};
}

/// Declares `units` instructions of arithmetic here ([`simt::declare!`]) with the
/// feature `model-arithmetic`; nothing without it.
#[cfg(not(feature = "model-arithmetic"))]
macro_rules! declare {
    ($units:expr) => {{
        let _ = (COST_PART, $units);
    }};
    ($units:expr, reads($record:expr, $words:expr)) => {{
        let _ = (COST_PART, $units, $words);
    }};
}
pub(crate) use declare;

/// Records the `words` 4-byte loads with which compiled code reads the fields it uses
/// of `record`, a reference into the scene ([`simt::read_words!`]), with the feature
/// `model-arithmetic`; nothing without it. (With arithmetic to declare at the same
/// place, `declare!(units, reads(record, words))`.)
#[cfg(feature = "model-arithmetic")]
macro_rules! reads {
    ($record:expr, $words:expr) => {
        simt::read_words!($record, $words)
    };
}

/// Nothing (without the feature `model-arithmetic`).
#[cfg(not(feature = "model-arithmetic"))]
macro_rules! reads {
    ($record:expr, $words:expr) => {{
        let _ = ($record, $words);
    }};
}
pub(crate) use reads;

/// `slice[i]`, which a kernel's ambient lane records as a load of global memory
/// ([`simt::read!`]) with the feature `model-arithmetic`: the scene's tables, which
/// kernels and CPU integrators read alike. A plain read without the feature.
#[cfg(feature = "model-arithmetic")]
macro_rules! read {
    ($slice:expr, $i:expr) => {
        simt::read!($slice, $i)
    };
}

/// `slice[i]` (without the feature `model-arithmetic`).
#[cfg(not(feature = "model-arithmetic"))]
macro_rules! read {
    ($slice:expr, $i:expr) => {
        $slice[$i]
    };
}
pub(crate) use read;

/// Whether a kernel's lane is counting the arithmetic that runs on this thread now
/// ([`simt::ambient::counting`]); never without the feature `model-arithmetic`. Shared
/// code that takes a shortcut its kernels' CUDA twins do not take (the same values, bit
/// for bit, from less work) takes it only when this is false, so that the model counts
/// the twins' work.
#[inline(always)]
pub(crate) fn counting() -> bool {
    #[cfg(feature = "model-arithmetic")]
    return simt::ambient::counting();
    #[cfg(not(feature = "model-arithmetic"))]
    false
}

/// The caller's inlined copy ([`simt::scope`]) with the feature `model-arithmetic`.
#[cfg(feature = "model-arithmetic")]
#[inline(always)]
#[track_caller]
pub(crate) fn scope() -> simt::Scope {
    simt::scope()
}

/// Nothing without the feature `model-arithmetic`.
#[cfg(not(feature = "model-arithmetic"))]
#[inline(always)]
pub(crate) fn scope() -> NoScope {
    NoScope
}

/// What [`scope`] returns without the feature `model-arithmetic`.
#[cfg(not(feature = "model-arithmetic"))]
pub(crate) struct NoScope;

/// The parts of the code whose declared work a kernel's statistics keep apart, named
/// by what the code is: each module that declares work says which it is
/// (`const COST_PART: Part = Part::Microfacet;`), and its work goes to the part's region
/// after the kernel's arithmetic region (`cis::shade` names them in this order, and
/// `gpu_check source --lines` groups the twin's source lines the same way).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Part {
    /// The kernel's own arithmetic.
    Kernel,
    /// The microfacet distribution and Fresnel terms ([`crate::bsdf::microfacet`]).
    Microfacet,
    /// The BSDFs' dispatch and lobes ([`crate::scene::Material`], layered stacks).
    Bsdf,
    /// Bidirectional strategies: connections, MIS weights, the light vertex cache's.
    Bidirectional,
    /// Sampling routines and random numbers ([`crate::sampling`]).
    Sampling,
    /// Light selection and sampling ([`crate::lights`]).
    Lights,
}

impl Part {
    /// Every part, in region order.
    #[cfg_attr(not(test), allow(dead_code))]
    pub const ALL: [Part; 6] =
        [Part::Kernel, Part::Microfacet, Part::Bsdf, Part::Bidirectional, Part::Sampling, Part::Lights];

    /// The part's region, counted after the kernel's arithmetic region.
    #[cfg_attr(not(any(test, feature = "model-arithmetic")), allow(dead_code))]
    pub const fn index(self) -> usize {
        self as usize
    }

    /// The part's name in a kernel's region list.
    #[cfg_attr(not(test), allow(dead_code))]
    pub const fn name(self) -> &'static str {
        match self {
            Part::Kernel => "kernel",
            Part::Microfacet => "microfacet",
            Part::Bsdf => "bsdf",
            Part::Bidirectional => "bidirectional",
            Part::Sampling => "sampling",
            Part::Lights => "lights",
        }
    }
}

#[cfg(test)]
mod tests {
    //! The weights nvcc's code gives (division, square root, `expf`, sine and cosine),
    //! derived from the stored SASS of `cuda/probe_costs.cu`
    //! (`docs/measured/probe-costs-sm90.sass`, printed by `sh cuda/probe_costs.sh`) and
    //! checked against the constants above.

    use crate::sass::{Inst, functions, target};

    /// The instructions a lane issues on the common path from the kernel's start to its
    /// exit: a predicated forward branch around a slow path (a block that calls a
    /// subroutine or loops back) is taken, any other falls through. Operand and address
    /// set-up (constant loads, the thread index, the address arithmetic, the global load
    /// and store, the exit) is left out, so what remains is the operation.
    fn common_path(code: &[Inst]) -> usize {
        let index = |at: u32| code.iter().position(|i| i.at == at).expect("a branch target in the function");
        let (mut k, mut n) = (0, 0);
        while k < code.len() {
            let i = &code[k];
            let setup =
                ["LDC", "ULDC", "S2R", "LDG", "STG", "EXIT", "IMAD.WIDE", "LEA"].iter().any(|p| i.op.starts_with(p))
                    || (i.op == "SHF.R.S32.HI" && i.args.contains("0x1f"));
            n += usize::from(!setup);
            if i.op == "EXIT" && !i.predicated {
                break;
            }
            if i.op == "BRA" {
                let to = target(i);
                if !i.predicated {
                    k = index(to);
                    continue;
                }
                let slow = to > i.at
                    && code[k + 1..index(to)]
                        .iter()
                        .any(|j| j.op.starts_with("CALL") || (j.op == "BRA" && target(j) < j.at));
                if slow {
                    k = index(to);
                    continue;
                }
            }
            k += 1;
        }
        n
    }

    #[test]
    fn the_weights_of_the_compiled_operations_are_their_sass_common_paths() {
        let sass = include_str!("../docs/measured/probe-costs-sm90.sass");
        let weight = |name: &str| -> u32 {
            let (_, code) = functions(sass).into_iter().find(|(n, _)| n == name).expect(name);
            common_path(&code) as u32
        };
        // The probe of one addition, to show the set-up is left out.
        assert_eq!(weight("probe_add"), 1);
        assert_eq!(weight("probe_div"), super::DIV);
        assert_eq!(weight("probe_sqrt"), super::SQRT);
        assert_eq!(weight("probe_exp"), super::EXP);
        // One weight for both: the longer (sinf 26, cosf 27).
        assert_eq!(weight("probe_sin").max(weight("probe_cos")), super::SIN_COS);
        assert_eq!((weight("probe_sin"), weight("probe_cos")), (26, 27));
    }
}

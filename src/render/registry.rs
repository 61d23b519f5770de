//! The integrators as every front end names them: one table that `warpray render
//! --integrator`, a scene file's `render.integrator`, `warpray converge --integrators`
//! and the inspector's menu all read, so a label means the same settings everywhere.

use super::options::CisParams;
use super::options::{IntegratorKind, LvcParams, RenderOptions};
use crate::error::{Error, Result};

/// An integrator with its settings, under a label: `path`, `light`, `bdpt`, `lvc`,
/// `lvc-mk` (LVC-BDPT as megakernels on the device), `cis`, and the CIS ablations
/// `cis-nosort`, `cis-nois` (uniform connections) and `cis-nocompact` (no compaction
/// or regeneration).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Variant {
    /// The label (command lines, charts, CSV, menus).
    pub label: &'static str,
    /// What it is, in a few words (help texts and menus).
    pub summary: &'static str,
    /// The integrator.
    pub kind: IntegratorKind,
    /// CIS-LBDPT switches (ablations).
    pub cis: CisParams,
    /// LVC-BDPT settings (the megakernel).
    pub lvc: LvcParams,
}

/// (label, summary) of every variant, in menu order.
const TABLE: [(&str, &str); 9] = [
    ("path", "path tracing with next-event estimation and MIS"),
    ("light", "light tracing, splatted through the camera"),
    ("bdpt", "bidirectional path tracing, MIS over all strategies"),
    ("lvc", "LVC-BDPT: light vertex cache, wavefronts on the host"),
    ("lvc-mk", "LVC-BDPT as megakernels on the simt device (same image as lvc)"),
    ("cis", "CIS-LBDPT: both passes streamed on simt, sorted, resampled connections"),
    ("cis-nosort", "CIS-LBDPT without sorting by material"),
    ("cis-nois", "CIS-LBDPT with uniform (not resampled) connections"),
    ("cis-nocompact", "CIS-LBDPT without compaction or regeneration"),
];

impl Variant {
    /// Every label [`Variant::parse`] accepts, in menu order.
    pub const NAMES: [&'static str; 9] = {
        let mut names = [""; 9];
        let mut i = 0;
        while i < TABLE.len() {
            names[i] = TABLE[i].0;
            i += 1;
        }
        names
    };

    /// The variant of a label (case-insensitive); an error lists the known ones.
    pub fn parse(name: &str) -> Result<Variant> {
        let (label, summary) = TABLE.iter().find(|(n, _)| n.eq_ignore_ascii_case(name)).copied().ok_or_else(|| {
            Error::BadSetting(format!("unknown integrator '{name}' (known: {})", Self::NAMES.join(", ")))
        })?;
        let d = CisParams::default();
        let (kind, cis) = match label {
            "path" => (IntegratorKind::Path, d),
            "light" => (IntegratorKind::Light, d),
            "bdpt" => (IntegratorKind::Bdpt, d),
            "lvc" => (IntegratorKind::Lvc, d),
            "lvc-mk" => (IntegratorKind::LvcMegakernel, d),
            "cis" => (IntegratorKind::Cis, d),
            "cis-nosort" => (IntegratorKind::Cis, CisParams { sort: false, ..d }),
            "cis-nois" => (IntegratorKind::Cis, CisParams { importance: false, ..d }),
            _ => (IntegratorKind::Cis, CisParams { regenerate: false, ..d }),
        };
        let lvc = LvcParams::default();
        Ok(Variant { label, summary, kind, cis, lvc })
    }

    /// Every variant, in menu order.
    pub fn all() -> Vec<Variant> {
        Self::NAMES.iter().map(|n| Self::parse(n).expect("every label in the table parses")).collect()
    }

    /// The plain integrator of `kind` (its label is the kind's name).
    pub fn of(kind: IntegratorKind) -> Variant {
        Self::parse(kind.name()).expect("every kind has a label")
    }

    /// `opts` set to render this variant: its integrator, CIS switches and LVC settings.
    pub fn apply(&self, opts: RenderOptions) -> RenderOptions {
        RenderOptions { integrator: self.kind, cis: self.cis, lvc: self.lvc, ..opts }
    }

    /// Every label with its summary, one per line (for help texts).
    pub fn help() -> String {
        TABLE.iter().map(|(l, s)| format!("  {l:<14} {s}\n")).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_label_parses_to_its_own_settings() {
        let all = Variant::all();
        assert_eq!(all.len(), TABLE.len());
        for v in &all {
            assert_eq!(Variant::parse(&v.label.to_uppercase()).unwrap(), *v);
            assert_eq!(v.kind == IntegratorKind::LvcMegakernel, v.label == "lvc-mk");
        }
        // Labels are distinct, and distinct labels mean distinct settings.
        for (i, a) in all.iter().enumerate() {
            for b in &all[i + 1..] {
                assert_ne!(a.label, b.label);
                assert!((a.kind, a.cis, a.lvc) != (b.kind, b.cis, b.lvc), "{} and {} are the same", a.label, b.label);
            }
        }
        for kind in IntegratorKind::ALL {
            assert_eq!(Variant::of(kind).kind, kind);
        }
        let cis = Variant::parse("cis-nois").unwrap().apply(RenderOptions::default());
        assert_eq!((cis.integrator, cis.cis.importance, cis.cis.sort), (IntegratorKind::Cis, false, true));
        let e = Variant::parse("pt").unwrap_err().to_string();
        assert!(e.contains("unknown integrator 'pt'") && e.contains("cis-nocompact"), "{e}");
    }
}

//! Reading stored `cuobjdump -sass` listings, for the tests that derive instruction
//! weights from the GPU twins' compiled code (`cost`'s probe weights, PDACRT's kernel
//! weights). Test-only: nothing in the renderer reads SASS.

/// One instruction: its address, whether it is predicated, its opcode and operands.
pub(crate) struct Inst {
    pub at: u32,
    pub predicated: bool,
    pub op: String,
    pub args: String,
}

/// The instructions of each function of a `cuobjdump -sass` listing, by (mangled) name.
pub(crate) fn functions(sass: &str) -> Vec<(String, Vec<Inst>)> {
    let mut out: Vec<(String, Vec<Inst>)> = Vec::new();
    for line in sass.lines() {
        if let Some(name) = line.trim().strip_prefix("Function : ") {
            out.push((name.trim().to_string(), Vec::new()));
        } else if let (Some(rest), Some(f)) = (line.trim().strip_prefix("/*"), out.last_mut()) {
            let (at, text) = rest.split_once("*/").expect("an address");
            let text = text.trim().trim_end_matches(';').trim();
            let (predicated, text) = match text.strip_prefix('@') {
                Some(t) => (true, t.split_once(' ').map_or("", |(_, r)| r.trim())),
                None => (false, text),
            };
            let (op, args) = text.split_once(' ').unwrap_or((text, ""));
            let at = u32::from_str_radix(at, 16).expect("a hex address");
            f.1.push(Inst { at, predicated, op: op.to_string(), args: args.to_string() });
        }
    }
    out
}

/// The one function whose name contains `name`.
pub(crate) fn function(sass: &str, name: &str) -> Vec<Inst> {
    let mut found = functions(sass).into_iter().filter(|(n, _)| n.contains(name));
    let (_, code) = found.next().unwrap_or_else(|| panic!("no function {name} in the listing"));
    assert!(found.next().is_none(), "more than one function named like {name}");
    code
}

/// The address a branch goes to.
pub(crate) fn target(i: &Inst) -> u32 {
    let hex = i.args.split("0x").last().expect("a branch target");
    u32::from_str_radix(hex.trim_end_matches(|c: char| !c.is_ascii_hexdigit()), 16).unwrap()
}

/// Whether `simt` counts the instruction itself, as a memory operation of the model
/// (global and shared loads, stores, reductions and atomics), rather than as declared
/// work.
pub(crate) fn is_memory(i: &Inst) -> bool {
    ["LDG", "STG", "LDS", "STS", "RED", "ATOM"].iter().any(|p| i.op.starts_with(p))
}

/// What one lane issues on a path: every instruction, and how many of them are memory
/// operations (`is_memory`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Path {
    pub issued: u32,
    pub memory: u32,
}

impl Path {
    /// The instructions `simt` leaves to declared work: all but the memory operations.
    pub(crate) fn work(self) -> u32 {
        self.issued - self.memory
    }
}

/// The path one lane takes from address `from` until it comes to `until` again or for
/// the first time (not counted). Each conditional branch on the way (a predicated `BRA`
/// or `EXIT`) takes the next of `taken`; an unconditional `BRA` is followed; an
/// unconditional `EXIT` ends the walk and is not counted (nor is a taken conditional
/// one's exit after it). Panics unless every decision is used, so that a path is named
/// completely.
pub(crate) fn walk(code: &[Inst], from: u32, until: u32, taken: &[bool]) -> Path {
    let index = |at: u32| code.iter().position(|i| i.at == at).unwrap_or_else(|| panic!("no instruction at {at:#x}"));
    let (mut k, mut next) = (index(from), 0);
    let mut path = Path { issued: 0, memory: 0 };
    loop {
        let i = &code[k];
        if (path.issued > 0 && i.at == until) || (i.op == "EXIT" && !i.predicated) {
            break;
        }
        path.issued += 1;
        path.memory += u32::from(is_memory(i));
        let branch = matches!(i.op.as_str(), "BRA" | "EXIT");
        let jump = branch
            && (!i.predicated || {
                let t = *taken.get(next).unwrap_or_else(|| panic!("no decision left for the branch at {:#x}", i.at));
                next += 1;
                t
            });
        match (jump, i.op.as_str()) {
            (true, "EXIT") => break,
            (true, _) => k = index(target(i)),
            _ => k += 1,
        }
    }
    assert_eq!(next, taken.len(), "decisions left over at the end of the walk from {from:#x}");
    path
}

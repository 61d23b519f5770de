//! The time model's unit tests: each bound its quantity over its rate, planted rate errors,
//! the chain's waits, occupancy, profiles read and written.

use super::*;
use crate::stats::{RegionStats, Traffic};

fn profile() -> GpuProfile {
    GpuProfile::named("h200").unwrap()
}

/// A measured launch of `grid` blocks of 256 threads whose every warp issues
/// `issued` instructions, `loads` of them loads, touching `sectors` sectors in all.
fn launch(grid: u32, issued: u64, loads: u64, sectors: u64, footprint: u64) -> LaunchRecord {
    let warps = grid as u64 * 8;
    LaunchRecord {
        name: "test::kernel",
        grid,
        block: 256,
        shared_bytes: 0,
        registers: 0,
        code_bytes: 0,
        seconds: 0.0,
        measured: true,
        threads: warps * 32,
        ops: RegionStats { name: "ops", issued: warps * issued, active: warps * issued * 32 },
        regions: Vec::new(),
        loads: Traffic { requests: warps * loads, sectors, lanes: warps * loads * 32 },
        stores: Traffic::default(),
        atomics: Traffic::default(),
        barriers: 0,
        footprint_sectors: footprint,
        loaded_footprint_sectors: footprint,
        block_sectors: sectors,
        longest_warp: WarpChain { instructions: issued, load_rounds: loads, ..WarpChain::default() },
        waits: WarpChain { instructions: warps * issued, load_rounds: warps * loads, ..WarpChain::default() },
        block_chains: WarpChain::default(),
        in_order: false,
    }
}

#[test]
fn every_shipped_profile_reads_and_writes_back_the_same() {
    for (name, _) in PROFILES {
        let p = GpuProfile::named(name).unwrap();
        let again = GpuProfile::parse(&p.to_text("header", |_| "src".into())).unwrap();
        for (a, b) in [(p.sms, again.sms), (p.hbm_bytes_per_s, again.hbm_bytes_per_s), (p.launch_s, again.launch_s)] {
            assert!((a - b).abs() <= 1e-3 * a, "{name}: {a} != {b}");
        }
    }
    assert!(GpuProfile::named("h100x").unwrap_err().contains("known: h200"));
}

#[test]
fn bad_profiles_name_the_line_and_key() {
    let text = GpuProfile::named("h200").unwrap().to_text("", |_| String::new());
    let e = GpuProfile::parse(&text.replace("hbm_gb_per_s = ", "hbm_gb_per_s = -")).unwrap_err();
    assert!(e.contains("hbm_gb_per_s") && e.contains("positive") && e.starts_with("line "), "{e}");
    let e = GpuProfile::parse(&text.replace("l2_bytes = ", "l2_bytez = ")).unwrap_err();
    assert!(e.contains("unknown key 'l2_bytez'"), "{e}");
    let without: String = text.lines().filter(|l| !l.starts_with("launch_us")).map(|l| format!("{l}\n")).collect();
    assert!(GpuProfile::parse(&without).unwrap_err().contains("missing key 'launch_us'"));
    let twice = format!("{text}sms = 1\n");
    assert!(GpuProfile::parse(&twice).unwrap_err().contains("given twice"));
    assert!(GpuProfile::parse(&text.replace("sms = ", "sms = nan # ")).is_err());
}

#[test]
fn each_bound_is_the_quantity_over_its_rate() {
    let p = profile();
    // Streaming: 1 GiB of first touches is HBM-bound.
    let sectors = (1u64 << 30) / 32;
    let t = predict(&launch(p.sms as u32 * 64, 40, 4, sectors, sectors), &p).unwrap();
    assert_eq!(t.bound(), "hbm");
    let hbm = (1u64 << 30) as f64 / p.hbm_bytes_per_s;
    // (plus the share of its issue bound the streaming warps do not hide)
    assert!((t.seconds - p.launch_s - hbm - p.exposed_free * t.issue).abs() < 1e-12 * hbm.max(1.0), "{t:?}");
    // The same traffic again, resident in L2 (no first touches): L2-bound.
    let t = predict(&launch(p.sms as u32 * 64, 40, 4, sectors, 0), &p).unwrap();
    assert_eq!(t.bound(), "l2");
    // Arithmetic only, a full machine: issue-bound, instructions over the rate.
    let r = launch(p.sms as u32 * 64, 100_000, 0, 0, 0);
    let t = predict(&r, &p).unwrap();
    let issue = r.ops.issued as f64 / (p.issue_per_cycle_per_sm * p.sms * p.clock_hz);
    assert_eq!(t.bound(), "issue");
    assert!((t.issue - issue).abs() < 1e-9 * issue);
    // One small block: a single warp's dependent chain.
    let t = predict(&launch(1, 1000, 10, 80, 80), &p).unwrap();
    assert_eq!(t.bound(), "latency");
    // Unmeasured launches have no prediction.
    assert!(predict(&LaunchRecord { measured: false, ..launch(1, 1, 1, 1, 1) }, &p).is_none());
}

#[test]
fn code_past_the_instruction_cache_bounds_issue_at_the_fetch_rate() {
    let p = profile();
    // Arithmetic only, a full machine: from code that fits, the issue rate bounds it.
    let fits = launch(p.sms as u32 * 64, 100_000, 0, 0, 0);
    let big = LaunchRecord { code_bytes: p.fetch_thrash_code_bytes as u32, ..fits.clone() };
    let small = LaunchRecord { code_bytes: p.fetch_thrash_code_bytes as u32 - 16, ..fits.clone() };
    for r in [&fits, &small] {
        let t = predict(r, &p).unwrap();
        assert_eq!((t.bound(), t.fetch), ("issue", 0.0));
    }
    // From code of the profile's threshold and more, the fetch rate does: the same
    // instructions over it.
    let t = predict(&big, &p).unwrap();
    let fetch = big.ops.issued as f64 / (p.fetch_issue_per_cycle_per_sm * p.sms * p.clock_hz);
    assert_eq!(t.bound(), "fetch");
    assert!((t.fetch - fetch).abs() < 1e-9 * fetch && (t.seconds - p.launch_s - fetch).abs() < 1e-9 * fetch);
    // A planted 5 % error in the fetch rate moves the prediction by as much.
    let planted = GpuProfile { fetch_issue_per_cycle_per_sm: p.fetch_issue_per_cycle_per_sm * 1.05, ..p.clone() };
    let moved = predict(&big, &planted).unwrap().seconds - p.launch_s;
    assert!((moved * 1.05 - fetch).abs() < 1e-9 * fetch, "{moved} against {fetch}");
    // One block's instructions are issued by one SM.
    let one = LaunchRecord { code_bytes: u32::MAX, ..launch(1, 1000, 10, 80, 80) };
    let t = predict(&one, &p).unwrap();
    assert!((t.fetch * p.fetch_issue_per_cycle_per_sm * p.clock_hz - 8000.0).abs() < 1e-6, "{t:?}");
}

#[test]
fn a_planted_error_in_one_rate_moves_only_its_bound() {
    let p = profile();
    let sectors = (1u64 << 30) / 32;
    let r = launch(p.sms as u32 * 64, 40, 4, sectors, sectors);
    let base = predict(&r, &p).unwrap();
    let planted = GpuProfile { hbm_bytes_per_s: p.hbm_bytes_per_s * 2.0, ..p.clone() };
    let t = predict(&r, &planted).unwrap();
    assert!((t.hbm * 2.0 - base.hbm).abs() < 1e-12, "{t:?}");
    assert_eq!((t.issue, t.l2, t.latency), (base.issue, base.l2, base.latency));
    assert!(t.seconds < base.seconds * 0.9);
}

#[test]
fn waited_atomics_and_fences_lengthen_the_chain_and_fences_have_their_own_bound() {
    let p = profile();
    // One warp: its chain gains each waited atomic's and fence's latency, and each
    // fenced sector's beyond one per fence.
    let mut r = launch(1, 100, 10, 80, 0);
    let base = predict(&r, &p).unwrap().latency;
    r.longest_warp.atomic_rounds = 3;
    r.longest_warp.fences = 2;
    r.longest_warp.fenced_sectors = 50;
    r.waits.atomic_rounds = 3;
    r.waits.fences = 2;
    r.waits.fenced_sectors = 50;
    let t = predict(&r, &p).unwrap();
    let added = 3.0 * p.atomic_latency_s + 2.0 * p.fence_latency_s + 48.0 * p.fenced_sector_latency_s;
    assert!((t.latency - base - added).abs() < 1e-12, "{t:?}");
    // A full machine fencing with little else: bound by the fences' rate and that of
    // the sectors they wait for, which planted errors move alone.
    let mut r = launch(p.sms as u32 * 64, 4, 0, 0, 0);
    r.waits.fences = 50_000_000;
    r.waits.fenced_sectors = 800_000_000;
    let t = predict(&r, &p).unwrap();
    assert_eq!(t.bound(), "fences");
    assert!((t.fences - (5e7 / p.fences_per_s + 8e8 / p.fenced_sectors_per_s)).abs() < 1e-12);
    let slow = predict(&r, &GpuProfile { fences_per_s: p.fences_per_s / 2.0, ..p.clone() }).unwrap();
    assert!((slow.fences - t.fences - 5e7 / p.fences_per_s).abs() < 1e-12 && slow.issue == t.issue);
    let slow = predict(&r, &GpuProfile { fenced_sectors_per_s: p.fenced_sectors_per_s / 2.0, ..p.clone() }).unwrap();
    assert!((slow.fences - t.fences - 8e8 / p.fenced_sectors_per_s).abs() < 1e-12 && slow.issue == t.issue);
}

#[test]
fn fences_wait_for_their_share_of_the_gpus_fence_rate_with_every_warp_fencing() {
    let p = profile();
    // Every warp's chain is ten fences waiting for 40 sectors: alone, their latencies;
    // with a full wave of warps in flight, those warps' fences at the GPU's rate.
    let fenced = |grid: u32| {
        let mut r = launch(grid, 4, 0, 0, 0);
        let warps = grid as u64 * 8;
        r.longest_warp = WarpChain { fences: 10, fenced_sectors: 40, ..r.longest_warp };
        r.waits = WarpChain { fences: 10 * warps, fenced_sectors: 40 * warps, ..r.waits };
        predict(&r, &p).unwrap()
    };
    let cycle = 1.0 / p.clock_hz;
    let alone = 4.0 * p.alu_latency_cycles * cycle + 10.0 * p.fence_latency_s + 30.0 * p.fenced_sector_latency_s;
    let one = fenced(1);
    assert!((one.latency - alone).abs() < 1e-15, "{one:?}");
    let resident = p.sms * 8.0 * 8.0;
    let loaded = resident * (10.0 / p.fences_per_s + 40.0 / p.fenced_sectors_per_s);
    assert!(loaded > 2.0 * alone);
    let full = fenced(p.sms as u32 * 8);
    assert!((full.latency - loaded).abs() < 1e-12 * loaded.max(1.0), "{full:?} against {loaded:e}");
}

#[test]
fn occupancy_follows_block_size_and_shared_memory() {
    let p = profile();
    assert_eq!(blocks_per_sm(&p, 256, 0, 0), (p.max_warps_per_sm / 8.0).floor());
    assert_eq!(blocks_per_sm(&p, 32, 0, 0), p.max_blocks_per_sm);
    assert_eq!(blocks_per_sm(&p, 128, 100_000, 0), (p.shared_per_sm_bytes / 100_000.0).floor());
    assert_eq!(blocks_per_sm(&p, 1024, 1 << 30, 0), 1.0);
    // 167 registers are allocated as 168: 5,376 per warp, 12 warps of 65,536, three
    // blocks of 128 threads; 32 registers leave the warp limit binding.
    assert_eq!(p.registers_per_sm, 65536.0);
    assert_eq!(blocks_per_sm(&p, 128, 0, 167), 3.0);
    assert_eq!(blocks_per_sm(&p, 256, 0, 32), (p.max_warps_per_sm / 8.0).floor());
    assert_eq!(blocks_per_sm(&p, 256, 0, 255), 1.0);
}

#[test]
fn a_sector_repeated_within_a_round_is_waited_for_once() {
    // One block of 8 warps, each one round of four loads whose 16 sectors are the same
    // (48 repeats a warp): 128 distinct sectors, all first touches. Counted over every
    // sector request (512) only a quarter of the waits would go to HBM; the round waits
    // for its sectors once, so all of them do.
    let p = profile();
    let mut r = launch(1, 4, 1, 512, 128);
    r.waits.round_repeats = 8 * 48;
    let chain = |t: &Prediction| t.latency;
    let once = chain(&predict(&r, &p).unwrap());
    let hbm_round = p.hbm_latency_s + 4.0 * p.alu_latency_cycles / p.clock_hz;
    assert!((once - hbm_round).abs() <= 1e-3 * hbm_round, "{once} against {hbm_round}");
    r.waits.round_repeats = 0;
    let diluted = chain(&predict(&r, &p).unwrap());
    let mixed = 0.25 * p.hbm_latency_s + 0.75 * p.l2_latency_s + 4.0 * p.alu_latency_cycles / p.clock_hz;
    assert!((diluted - mixed).abs() <= 1e-3 * mixed, "{diluted} against {mixed}");
}

#[test]
fn only_the_loads_first_touches_make_them_wait_for_hbm() {
    // One block whose warps load 64 sectors already in L2 (two rounds each) and store
    // 64 fresh ones: the stores' first touches are written back (the HBM bound counts
    // them) but no load waits for them. The launch's whole footprint over every sector
    // touched (the model's share before it counted the loads' own) would send half of
    // the rounds to HBM, which the first check catches.
    let p = profile();
    let mut r = launch(1, 4, 2, 64, 64);
    r.loaded_footprint_sectors = 0;
    r.stores = Traffic { requests: 2, sectors: 64, lanes: 64 };
    let t = predict(&r, &p).unwrap();
    let l2_rounds = 2.0 * p.l2_latency_s + 4.0 * p.alu_latency_cycles / p.clock_hz;
    assert!((t.latency - l2_rounds).abs() <= 1e-3 * l2_rounds, "{} against {l2_rounds}", t.latency);
    assert!((t.hbm - 64.0 * SECTOR_BYTES as f64 / p.hbm_bytes_per_s).abs() < 1e-15);
    // Half the loaded sectors first touched: half the rounds' waits go to HBM.
    r.loaded_footprint_sectors = 32;
    let half = predict(&r, &p).unwrap().latency;
    let mixed = p.hbm_latency_s + p.l2_latency_s + 4.0 * p.alu_latency_cycles / p.clock_hz;
    assert!((half - mixed).abs() <= 1e-3 * mixed, "{half} against {mixed}");
}

#[test]
fn sectors_a_request_touches_one_word_of_cross_l2_at_the_scattered_rate() {
    // One warp's loads of 32 lanes: one sector a lane (scattered), eight lanes a sector
    // (coalesced 4-byte words), and in between by the words filled.
    let p = profile();
    let l2 = |lanes_per_sector: f64| {
        let r = launch(1, 4, 4, (8.0 * 4.0 * 32.0 / lanes_per_sector) as u64, 0);
        let t = predict(&r, &p).unwrap();
        t.l2 / (r.block_sectors as f64 * SECTOR_BYTES as f64)
    };
    let close = |a: f64, b: f64| (a - b).abs() <= 1e-9 * b;
    assert!(close(l2(1.0), 1.0 / p.l2_scattered_bytes_per_s));
    assert!(close(l2(8.0), 1.0 / p.l2_bytes_per_s));
    // Four lanes a sector fill half its words: 4/7 of the way from coalesced to scattered.
    assert!(close(l2(4.0), 4.0 / 7.0 / p.l2_scattered_bytes_per_s + 3.0 / 7.0 / p.l2_bytes_per_s));
    assert!(l2(1.0) > 1.4 * l2(8.0), "the H200's scattered L2 rate is two thirds of the coalesced one");
}

#[test]
fn a_single_pass_launch_waits_for_its_look_back_hops_of_32_tiles() {
    let p = profile();
    let latency = |r: &LaunchRecord| predict(r, &p).unwrap().latency;
    let plain = launch(1000, 50, 2, 16_000, 16_000);
    let ordered = LaunchRecord { in_order: true, ..plain.clone() };
    // 999 tiles before the last: 32 hops, each two L2 latencies (statuses stored and
    // read) with no fence while the look-back makes none.
    let hops = 32.0;
    let hop = 2.0 * p.l2_latency_s;
    assert!((latency(&ordered) - latency(&plain) - hops * hop).abs() < 1e-12);
    // A look-back that fences (values wider than their status word) adds one fence a hop.
    let fenced = |r: &LaunchRecord| LaunchRecord { waits: WarpChain { fences: 3000, ..r.waits }, ..r.clone() };
    let gap = latency(&fenced(&ordered)) - latency(&fenced(&plain));
    assert!((gap - hops * (hop + p.fence_latency_s)).abs() < 1e-12);
    // One tile has no look-back; 33 tiles one hop.
    let one = LaunchRecord { grid: 1, in_order: true, ..plain.clone() };
    assert_eq!(latency(&one), latency(&LaunchRecord { grid: 1, ..plain.clone() }));
    let few = |grid| LaunchRecord { grid, in_order: true, ..plain.clone() };
    assert!((latency(&few(33)) - latency(&LaunchRecord { grid: 33, ..plain.clone() }) - hop).abs() < 1e-12);
}

#[test]
fn a_wave_lasts_as_long_as_its_blocks_slowest_warps() {
    let p = profile();
    // Four waves of blocks whose warps load 10 times each on average, while one warp
    // of each block loads 40 times: a block holds its slot for 40 rounds, so each wave
    // waits 40 rounds, not 10.
    let grid = (p.sms * p.max_warps_per_sm / 8.0) as u32 * 4;
    let even = launch(grid, 100, 10, 1_000_000, 0);
    let skewed = LaunchRecord {
        block_chains: WarpChain {
            instructions: 130 * grid as u64,
            load_rounds: 40 * grid as u64,
            ..WarpChain::default()
        },
        ..even.clone()
    };
    let (a, b) = (predict(&even, &p).unwrap(), predict(&skewed, &p).unwrap());
    assert_eq!((a.bound(), b.bound()), ("latency", "latency"));
    let round = p.l2_latency_s;
    let added = 4.0 * (30.0 * round + 30.0 * p.alu_latency_cycles / p.clock_hz);
    assert!((b.latency - a.latency - added).abs() < 1e-3 * added, "{a:?} {b:?}");
    // A block's chain is never taken for less than its mean warp's (a file's blocks
    // summed as none read as older files do).
    let short = LaunchRecord { block_chains: WarpChain { load_rounds: 1, ..WarpChain::default() }, ..even.clone() };
    assert_eq!(predict(&short, &p).unwrap().latency, a.latency);
}

/// How the bounds combine (the overlap probes): blocks whose barriers keep their warps
/// in one phase add the share `exposed_one_block` of the smaller of memory and
/// execution to the larger with one block a SM, falling towards `exposed_many_blocks`
/// as one over the blocks an SM holds; warps that run free add `exposed_free` of the
/// smaller of memory and issue, and a chain longer than both keeps the launch.
#[test]
fn the_bounds_overlap_as_the_probes_say() {
    let p = GpuProfile { exposed_free: 0.25, exposed_one_block: 1.0, exposed_many_blocks: 0.5, ..profile() };
    let sectors = (64u64 << 20) / 32;
    // One block a SM, L2-bound, with a dependent chain of a quarter of it: the two add.
    let phased = |grid: u32| {
        let r = LaunchRecord { barriers: grid as u64 * 4, ..launch(grid, 2_000, 4, sectors, 0) };
        let t = predict(&r, &p).unwrap();
        let (memory, execution) = (t.l2, t.latency.max(t.issue));
        assert!(memory > execution && execution > 0.1 * memory, "{t:?}");
        (t, memory, execution)
    };
    let (t, memory, execution) = phased(p.sms as u32);
    assert!((t.seconds - p.launch_s - memory - execution).abs() < 1e-9 * memory, "{t:?}");
    // Four blocks a SM: half of it, and a quarter of the one block's other half.
    let (t, memory, execution) = phased(4 * p.sms as u32);
    let share = 0.5 + 0.5 / 4.0;
    assert!((t.seconds - p.launch_s - memory - share * execution).abs() < 1e-9 * memory, "{t:?}");
    // The same launch without barriers: a quarter of its issue bound, not of its chain.
    let free = predict(&launch(4 * p.sms as u32, 2_000, 4, sectors, 0), &p).unwrap();
    assert!((free.seconds - p.launch_s - free.l2 - 0.25 * free.issue).abs() < 1e-9 * free.l2, "{free:?}");
    // A chain longer than memory and issue together sets the launch alone.
    let chained = predict(&launch(1, 100_000, 100, 800, 0), &p).unwrap();
    assert!(chained.latency > chained.l2 + chained.issue);
    assert!((chained.seconds - p.launch_s - chained.latency).abs() < 1e-15, "{chained:?}");
}

#[test]
fn the_overlap_shares_are_read_from_0_to_1() {
    let text = profile().to_text("", |_| String::new());
    let zero = text.replace("overlap_exposed_free = ", "overlap_exposed_free = 0 # ");
    assert_eq!(GpuProfile::parse(&zero).unwrap().exposed_free, 0.0);
    let over = text.replace("overlap_exposed_one_block = ", "overlap_exposed_one_block = 1.5 # ");
    let e = GpuProfile::parse(&over).unwrap_err();
    assert!(e.contains("overlap_exposed_one_block") && e.contains("from 0 to 1"), "{e}");
    let nan = text.replace("overlap_exposed_free = ", "overlap_exposed_free = nan # ");
    assert!(GpuProfile::parse(&nan).unwrap_err().contains("from 0 to 1"));
    // A profile written before the overlap probes says what to run.
    let older: String =
        text.lines().filter(|l| !l.starts_with("overlap_exposed_many")).map(|l| format!("{l}\n")).collect();
    assert!(GpuProfile::parse(&older).unwrap_err().contains("MODE=overlap"));
}

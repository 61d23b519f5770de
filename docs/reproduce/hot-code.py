#!/usr/bin/env python3
"""How much code a kernel's warps run, from Nsight Compute's source view exported as CSV
with SASS (`cuda/hot_code.sh`, or the reduced copies in docs/measured): per profiled
launch, the kernel's instructions, those executed at least once, and the fewest bytes of
instructions that hold 90, 99 and 99.9 % of the warp instructions issued (16 bytes an
instruction on sm_90).

    python3 docs/reproduce/hot-code.py gpu-out/source-*.csv.gz
    python3 docs/reproduce/hot-code.py --reduce IN.csv.gz OUT.csv.gz   # keep 3 columns
"""
import csv
import gzip
import io
import sys

KEEP = ["Address", "Instructions Executed", "Warp Stall Sampling (All Samples)"]


def sections(path):
    """(kernel line, rows) per profiled launch: each starts with a "Kernel Name" line."""
    opener = gzip.open if path.endswith(".gz") else open
    out = []
    for line in opener(path, "rt", errors="replace").read().splitlines():
        if line.startswith('"Kernel Name"'):
            out.append((line, []))
        elif out:
            out[-1][1].append(line)
    return [(k, list(csv.reader(io.StringIO("\n".join(body))))) for k, body in out]


def report(path):
    for kernel, rows in sections(path):
        header = rows[0]
        col = header.index("Instructions Executed")
        issued = []
        for r in rows[1:]:
            try:
                issued.append(float(r[col].replace(",", "")))
            except (IndexError, ValueError):
                pass
        total = sum(issued)
        hot = sorted((n for n in issued if n > 0), reverse=True)

        def kib_holding(share):
            acc = 0.0
            for k, n in enumerate(hot):
                acc += n
                if acc >= share * total:
                    return (k + 1) * 16 / 1024
            return len(hot) * 16 / 1024

        name = next(csv.reader([kernel]))[1]
        print(
            f"{path}: {name[:70]}: {len(issued) * 16 / 1024:.0f} KiB of code, {len(hot) * 16 / 1024:.0f} KiB "
            f"executed; 90 % of {total:.3g} issues in {kib_holding(0.9):.1f} KiB, 99 % in {kib_holding(0.99):.1f}, "
            f"99.9 % in {kib_holding(0.999):.1f}"
        )


def reduce(src, dst):
    with gzip.open(dst, "wt") as out:
        w = csv.writer(out, quoting=csv.QUOTE_ALL)
        last = None
        for kernel, rows in sections(src):
            if (kernel, rows) == last:
                continue  # Nsight's export repeats a launch's section
            last = (kernel, rows)
            out.write(kernel + "\n")
            cols = [rows[0].index(c) for c in KEEP]
            for r in rows:
                if len(r) > max(cols):
                    w.writerow([r[c] for c in cols])


if __name__ == "__main__":
    if sys.argv[1:2] == ["--reduce"]:
        reduce(sys.argv[2], sys.argv[3])
    else:
        for p in sys.argv[1:]:
            report(p)

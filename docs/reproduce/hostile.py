"""A held-out corpus of hostile inputs, run against the `warpray` binary: files and
flags written for this check, not taken from the tests or the fuzz seeds (Mitsuba XML,
PLY, TOML scenes, render flags, `diff`, `converge`, special files). Each case runs in
its own process with a time limit and an address-space limit, and is classified:

  ok       exit 0
  error    exit 1 or 2 with a message starting "error:" (a typed error)
  panic    a Rust panic (exit 101 or "panicked at")
  crash    killed by a signal (abort, segfault, stack overflow)
  hang     still running at the time limit
  oom      an allocation failed under the address-space limit

Only ok and error are acceptable. Run from the repository root after
`cargo build --release`:

  python3 docs/reproduce/hostile.py [WARPRAY] > docs/measured/hostile-held-out-corpus.txt

The exit status is 1 when any case is unacceptable.
"""
import gzip
import os
import resource
import struct
import subprocess
import sys
import tempfile
import time
import zlib

WARPRAY = os.path.abspath(sys.argv[1] if len(sys.argv) > 1 else "target/release/warpray")
TIME_LIMIT = 60
MEMORY_LIMIT = 8 << 30  # address space, bytes

CAM = """<sensor type="perspective"><float name="fov" value="40"/>
<transform name="to_world"><lookat origin="0,0,4" target="0,0,0" up="0,1,0"/></transform>
<film type="hdrfilm"><integer name="width" value="{w}"/><integer name="height" value="{h}"/></film></sensor>"""
LIGHT = """<shape type="sphere"><point name="center" x="0" y="2" z="1"/><float name="radius" value="0.3"/>
<emitter type="area"><rgb name="radiance" value="5"/></emitter></shape>"""


def xml(body, w=8, h=8):
    return f'<scene version="3.0.0">\n{CAM.format(w=w, h=h)}\n{LIGHT}\n{body}\n</scene>\n'


def ply_head(nv, nf, fmt="ascii", vtype="float", list_count="uchar", list_index="int", extra=""):
    return (f"ply\nformat {fmt} 1.0\nelement vertex {nv}\nproperty {vtype} x\nproperty {vtype} y\n"
            f"property {vtype} z\n{extra}element face {nf}\nproperty list {list_count} {list_index} vertex_indices\n"
            "end_header\n")


def png_chunk(kind, data):
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)


def png(width, height, bit_depth=8, color=2, idat=b""):
    head = struct.pack(">IIBBBBB", width, height, bit_depth, color, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + png_chunk(b"IHDR", head) + png_chunk(b"IDAT", zlib.compress(idat)) + png_chunk(b"IEND", b"")


def cases():
    """(name, argv, files to write {name: bytes}) for every case."""
    w = lambda name, data: (name, data if isinstance(data, bytes) else data.encode())
    tri = ply_head(3, 1) + "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n"
    quad_scene = xml('<shape type="rectangle"><bsdf type="diffuse"/></shape>')
    yield "xml: 100k nested <transform> steps", ["s.xml"], [w("s.xml", xml(
        '<shape type="rectangle"><transform name="to_world">' + "<translate x=\"0\">" * 100_000 +
        "</translate>" * 100_000 + "</transform></shape>"))]
    yield "xml: 300k nested unknown elements", ["s.xml"], [w("s.xml", xml("<a>" * 300_000 + "</a>" * 300_000))]
    yield "xml: billion laughs entities", ["s.xml"], [w("s.xml", '<?xml version="1.0"?><!DOCTYPE s [<!ENTITY a "aaaaaaaaaa">'
        + "".join(f'<!ENTITY {chr(98 + i)} "' + f"&{chr(97 + i)};" * 10 + '">' for i in range(9))
        + ']><scene version="3.0.0"><string name="x" value="&j;"/></scene>')]
    yield "xml: 10k nested twosided inside one shape", ["s.xml"], [w("s.xml", xml(
        '<shape type="rectangle">' + '<bsdf type="twosided">' * 10_000 + '<bsdf type="diffuse"/>' +
        "</bsdf>" * 10_000 + "</shape>"))]
    yield "xml: max_depth 1e20", ["s.xml"], [w("s.xml", xml('<integrator type="path"><integer name="max_depth" value="100000000000000000000"/></integrator>' + '<shape type="rectangle"/>'))]
    yield "xml: film 1e9 wide", ["s.xml"], [w("s.xml", xml('<shape type="rectangle"/>', w=1_000_000_000, h=1))]
    yield "xml: film width -8", ["s.xml"], [w("s.xml", xml('<shape type="rectangle"/>', w=-8))]
    yield "xml: sphere radius 1e30", ["s.xml"], [w("s.xml", xml('<shape type="sphere"><float name="radius" value="1e30"/></shape>'))]
    yield "xml: sphere centre nan", ["s.xml"], [w("s.xml", xml('<shape type="sphere"><point name="center" x="nan" y="0" z="0"/></shape>'))]
    yield "xml: scale 0 transform", ["s.xml"], [w("s.xml", xml('<shape type="rectangle"><transform name="to_world"><scale value="0"/></transform></shape>'))]
    yield "xml: lookat origin = target", ["s.xml"], [w("s.xml", quad_scene.replace('origin="0,0,4"', 'origin="0,0,0"'))]
    yield "xml: fov 180", ["s.xml"], [w("s.xml", quad_scene.replace('value="40"', 'value="180"'))]
    yield "xml: 50k spheres", ["s.xml"], [w("s.xml", xml("".join(
        f'<shape type="sphere"><point name="center" x="{i % 100}" y="{i // 100}" z="-5"/><float name="radius" value="0.4"/></shape>'
        for i in range(50_000))))]
    yield "xml: ply filename /dev/zero", ["s.xml"], [w("s.xml", xml('<shape type="ply"><string name="filename" value="/dev/zero"/></shape>'))]
    yield "xml: ply filename a directory", ["s.xml"], [w("s.xml", xml('<shape type="ply"><string name="filename" value="."/></shape>'))]
    yield "xml: obj filename /dev/urandom", ["s.xml"], [w("s.xml", xml('<shape type="obj"><string name="filename" value="/dev/urandom"/></shape>'))]
    yield "xml: ply of 2^31 vertices, no data", ["s.xml"], [w("s.xml", xml('<shape type="ply"><string name="filename" value="m.ply"/></shape>')), w("m.ply", ply_head(2**31, 1))]
    yield "xml: int_ior name unknown", ["s.xml"], [w("s.xml", xml('<shape type="rectangle"><bsdf type="dielectric"><string name="int_ior" value="unobtainium"/></bsdf></shape>'))]
    yield "xml: roughplastic alpha -1", ["s.xml"], [w("s.xml", xml('<shape type="rectangle"><bsdf type="roughplastic"><float name="alpha" value="-1"/></bsdf></shape>'))]
    yield "xml: plastic int_ior 1e30", ["s.xml"], [w("s.xml", xml('<shape type="rectangle"><bsdf type="plastic"><float name="int_ior" value="1e30"/></bsdf></shape>'))]
    yield "xml: rr_depth 0", ["s.xml"], [w("s.xml", xml('<integrator type="path"><integer name="rr_depth" value="0"/></integrator><shape type="rectangle"/>'))]
    yield "xml: spp 1e12", ["s.xml"], [w("s.xml", quad_scene.replace("</film>", "</film><sampler type=\"independent\"><integer name=\"sample_count\" value=\"1000000000000\"/></sampler>"))]
    yield "xml: invalid utf-8", ["s.xml"], [("s.xml", b'<scene version="3.0.0">\xff\xfe</scene>')]
    yield "xml: empty file", ["s.xml"], [("s.xml", b"")]
    yield "xml: the file is /dev/null", ["/dev/null"], []
    yield "ply: face list of 255 huge indices", ["m.ply"], [w("m.ply", ply_head(3, 1) + "0 0 0\n1 0 0\n0 1 0\n255 " + " ".join(["4000000000"] * 255) + "\n")]
    yield "ply: binary list count 4e9", ["m.ply"], [("m.ply", ply_head(3, 1, "binary_little_endian", list_count="uint").encode() + struct.pack("<9f", 0, 0, 0, 1, 0, 0, 0, 1, 0) + struct.pack("<I", 4_000_000_000))]
    yield "ply: 10 MB header line", ["m.ply"], [w("m.ply", "ply\nformat ascii 1.0\ncomment " + "x" * 10_000_000 + "\n" + tri[len("ply\nformat ascii 1.0\n"):])]
    yield "ply: 100k properties", ["m.ply"], [w("m.ply", ply_head(3, 1, extra="".join(f"property float p{i}\n" for i in range(100_000))) + tri[len(ply_head(3, 1)):])]
    yield "ply: unknown format", ["m.ply"], [w("m.ply", tri.replace("ascii", "binary_middle_endian"))]
    yield "ply: inf vertex", ["m.ply"], [w("m.ply", tri.replace("1 0 0", "inf 0 0"))]
    yield "ply: 1e39 vertex", ["m.ply"], [w("m.ply", tri.replace("1 0 0", "1e39 0 0"))]
    yield "ply: double 1e300 vertex", ["m.ply"], [("m.ply", ply_head(3, 1, "binary_little_endian", vtype="double").encode() + struct.pack("<9d", 0, 0, 0, 1e300, 0, 0, 0, 1, 0) + bytes([3]) + struct.pack("<3i", 0, 1, 2))]
    yield "ply: truncated binary", ["m.ply"], [("m.ply", ply_head(3, 1, "binary_little_endian").encode() + b"\x00" * 7)]
    yield "ply: gzip named .ply", ["m.ply"], [("m.ply", gzip.compress(tri.encode()))]
    yield "toml: mesh /dev/urandom", ["s.toml"], [w("s.toml", '[[mesh]]\nfile = "/dev/urandom"\n')]
    yield "toml: mesh is the scene itself", ["s.toml"], [w("s.toml", '[[mesh]]\nfile = "s.toml"\n')]
    yield "toml: camera fov nan", ["s.toml"], [w("s.toml", '[camera]\nposition = [0,0,4]\nlook_at = [0,0,0]\nfov = nan\n[[mesh]]\nfile = "m.ply"\n'), w("m.ply", tri)]
    yield "toml: 100k nested arrays", ["s.toml"], [w("s.toml", "x = " + "[" * 100_000 + "]" * 100_000 + "\n")]
    yield "toml: 100k nested inline tables", ["s.toml"], [w("s.toml", "x = " + "{a=" * 50_000 + "1" + "}" * 50_000 + "\n")]
    yield "toml: spp 2^40", ["s.toml"], [w("s.toml", '[render]\nspp = 1099511627776\n[[mesh]]\nfile = "m.ply"\n'), w("m.ply", tri)]
    yield "toml: 200k materials", ["s.toml"], [w("s.toml", "".join(f'[[material]]\nname = "m{i}"\ntype = "diffuse"\nalbedo = [0.5,0.5,0.5]\n' for i in range(200_000)))]
    yield "flags: --size 0x0", ["cornell", "--size", "0x0"], []
    yield "flags: --size 100000x1", ["cornell", "--size", "100000x1", "--spp", "1"], []
    yield "flags: --size 16384x16384 path", ["cornell", "--size", "16384x16384", "--spp", "1"], []
    yield "flags: --spp 0", ["cornell", "--spp", "0"], []
    yield "flags: --spp 2^32", ["cornell", "--spp", "4294967296"], []
    yield "flags: --seconds nan", ["cornell", "--seconds", "nan"], []
    yield "flags: --seconds 1e-30", ["cornell", "--size", "8x8", "--seconds", "1e-30"], []
    yield "flags: --threads 100000", ["cornell", "--threads", "100000"], []
    yield "flags: --max-depth 2^32-1", ["cornell", "--size", "8x8", "--spp", "1", "--max-depth", "4294967295"], []
    yield "flags: --filter gaussian:0:0", ["cornell", "--filter", "gaussian:0:0"], []
    yield "flags: --filter gaussian:1e30:2", ["cornell", "--filter", "gaussian:1e30:2"], []
    yield "flags: --exposure -1", ["cornell", "--exposure", "-1"], []
    yield "flags: --rr-depth 0", ["cornell", "--rr-depth", "0"], []
    yield "flags: -o into a missing folder", ["cornell", "--size", "8x8", "--spp", "1", "-o", "no/such/dir/x.png"], []
    yield "flags: -o where nothing can be written", ["cornell", "--size", "8x8", "--spp", "1", "-o", "/proc/x.png"], []
    yield "flags: -o with unknown extension", ["cornell", "--size", "8x8", "-o", "x.bmp"], []
    yield "flags: -o twice the same", ["cornell", "--size", "8x8", "--spp", "1", "-o", "a.png", "-o", "a.png"], []
    yield "flags: --megakernel with path", ["cornell", "--megakernel", "--integrator", "path"], []
    yield "diff: images of different sizes", ["diff", "a8.png", "a16.png"], [("a8.png", png(8, 8, idat=b"".join(b"\x00" + b"\x80" * 24 for _ in range(8)))), ("a16.png", png(16, 16, idat=b"".join(b"\x00" + b"\x80" * 48 for _ in range(16))))]
    yield "diff: PNG claiming 60000x60000", ["diff", "big.png", "big.png"], [("big.png", png(60000, 60000, idat=b"\x00" * 1000))]
    yield "diff: PNG 1-bit 65535 square", ["diff", "bits.png", "bits.png"], [("bits.png", png(65535, 65535, bit_depth=1, color=0, idat=b"\x00" * 8193 * 64))]
    yield "diff: corrupt PNG data", ["diff", "c.png", "c.png"], [("c.png", png(8, 8)[:40] + b"\x00" * 30)]
    yield "diff: --fail-above -1", ["diff", "a8.png", "a8.png", "--fail-above", "-1"], [("a8.png", png(8, 8, idat=b"".join(b"\x00" + b"\x80" * 24 for _ in range(8))))]
    yield "diff: --epsilon nan", ["diff", "a8.png", "a8.png", "--epsilon", "nan"], [("a8.png", png(8, 8, idat=b"".join(b"\x00" + b"\x80" * 24 for _ in range(8))))]
    yield "diff: a directory", ["diff", ".", "."], []
    yield "diff: /dev/zero", ["diff", "/dev/zero", "/dev/zero"], []
    csv = "integrator,seconds,spp,rmse,relmse\n"
    yield "converge --replot: empty", ["converge", "cornell", "--replot", "c.csv", "-o", "r"], [w("c.csv", "")]
    yield "converge --replot: header only", ["converge", "cornell", "--replot", "c.csv", "-o", "r"], [w("c.csv", csv)]
    yield "converge --replot: seconds 1e308 to 1e-308", ["converge", "cornell", "--replot", "c.csv", "-o", "r"], [w("c.csv", csv + "path,1e-308,1,1e-308,1e-308\npath,1e308,2,1e308,1e308\n")]
    yield "converge --replot: negative and zero", ["converge", "cornell", "--replot", "c.csv", "-o", "r"], [w("c.csv", csv + "path,-1,1,0,-5\npath,0,2,-0,0\n")]
    yield "converge --replot: 200k rows", ["converge", "cornell", "--replot", "c.csv", "-o", "r"], [w("c.csv", csv + "".join(f"bdpt,{i * 0.01 + 0.01},{i + 1},{1 / (i + 1)},{2 / (i + 1)}\n" for i in range(200_000)))]
    yield "converge --replot: unknown integrator", ["converge", "cornell", "--replot", "c.csv", "-o", "r"], [w("c.csv", csv + "warp-drive,1,1,0.1,0.1\n")]
    yield "converge: reference-spp 0", ["converge", "cornell", "--reference-spp", "0", "--seconds", "1", "-o", "r"], []
    yield "converge: seconds inf", ["converge", "cornell", "--seconds", "inf", "-o", "r"], []
    yield "converge: reference a text file", ["converge", "cornell", "--reference", "t.exr", "--seconds", "1", "-o", "r"], [w("t.exr", "not an exr")]


def run(argv, cwd):
    def limits():
        resource.setrlimit(resource.RLIMIT_AS, (MEMORY_LIMIT, MEMORY_LIMIT))
    start = time.time()
    try:
        p = subprocess.run([WARPRAY, *argv], cwd=cwd, capture_output=True, timeout=TIME_LIMIT, preexec_fn=limits)
    except subprocess.TimeoutExpired:
        return "hang", time.time() - start, ""
    err = p.stderr.decode(errors="replace")
    last = next((l for l in reversed(err.strip().splitlines()) if l.strip()), "")
    if "memory allocation of" in err or ("out of memory" in err.lower() and p.returncode < 0):
        kind = "oom"
    elif p.returncode == 101 or "panicked at" in err:
        kind = "panic"
    elif p.returncode < 0:
        kind = "crash"
    elif p.returncode == 0:
        kind = "ok"
    elif p.returncode in (1, 2) and "error" in err.lower():
        kind = "error"
    else:
        kind = f"exit {p.returncode}"
    return kind, time.time() - start, last


bad = 0
counts = {}
print(f"warpray: {WARPRAY}; limits: {TIME_LIMIT} s, {MEMORY_LIMIT >> 30} GiB of address space")
for name, argv, files in cases():
    with tempfile.TemporaryDirectory() as d:
        for fname, data in files:
            with open(os.path.join(d, fname), "wb") as f:
                f.write(data)
        kind, seconds, last = run(argv, d)
    counts[kind] = counts.get(kind, 0) + 1
    flag = "" if kind in ("ok", "error") else "  <-- UNACCEPTABLE"
    bad += bool(flag)
    print(f"{kind:6} {seconds:6.1f} s  {name}: {last[:160]}{flag}", flush=True)
print("totals: " + ", ".join(f"{k} {v}" for k, v in sorted(counts.items())))
sys.exit(1 if bad else 0)

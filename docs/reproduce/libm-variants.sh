#!/bin/sh
# Whether images depend on which of glibc's libm variants runs: glibc picks FMA/AVX2
# or SSE2 versions of expf, sincosf, exp, sin, cos, ... by CPU (ifunc), so a machine
# without FMA runs other code. GLIBC_TUNABLES makes this machine take the SSE2 ones.
#
#   cargo build --release
#   sh docs/reproduce/libm-variants.sh [sweep]
#
# Renders scenes x integrators with both variants and diffs the images; with `sweep`
# also hashes every float input of the float functions (about 5 min) and 2^26 random
# inputs of the double ones under both variants (docs/reproduce/libm_sweep.c).
set -eu
w=${WARPRAY:-target/release/warpray}
sse2="glibc.cpu.hwcaps=-AVX2,-FMA,-AVX2_Usable,-FMA_Usable"
tmp=$(mktemp -d)
echo "# $(ldd --version | head -1); $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //')"
for scene in assets/scenes/mitsuba-cbox.xml assets/scenes/materials.toml assets/scenes/bedroom.toml \
    assets/scenes/bsdf/plastic.xml assets/scenes/bsdf/roughplastic.xml assets/scenes/bsdf/roughdielectric.xml; do
    for integrator in path light bdpt lvc lvc-mk cis; do
        "$w" render "$scene" --integrator "$integrator" --spp 4 --size 64x64 -o "$tmp/fma.exr" > /dev/null
        GLIBC_TUNABLES=$sse2 "$w" render "$scene" --integrator "$integrator" --spp 4 --size 64x64 -o "$tmp/sse2.exr" > /dev/null
        echo "$scene $integrator: $("$w" diff "$tmp/fma.exr" "$tmp/sse2.exr" | tail -1)"
    done
done
if [ "${1:-}" = sweep ]; then
    cc -O2 -o "$tmp/sweep" docs/reproduce/libm_sweep.c -lm
    "$tmp/sweep" > "$tmp/fma.txt" & GLIBC_TUNABLES=$sse2 "$tmp/sweep" > "$tmp/sse2.txt"; wait
    paste "$tmp/fma.txt" "$tmp/sse2.txt" | awk '{ print $1, ($NF == $(NF/2) ? "same" : "differs") }'
fi
rm -r "$tmp"

#!/bin/sh
# The runtime table of docs/lvc-cis.md ("The paper's experiment"): the Cornell box and
# the two rooms, a BDPT reference of 2048 spp each, then two `converge` runs of six
# integrators for 8 s each, the second in the opposite order.
#
#   cargo build --release
#   sh docs/reproduce/paper-runtime-table.sh OUT [WARPRAY_BINARY]
set -eu
out=${1:?usage: paper-runtime-table.sh OUT [WARPRAY_BINARY]}
w=${2:-target/release/warpray}
mkdir -p "$out/run1" "$out/run2"
for s in cornell:cornell assets/scenes/white-room.toml:white-room assets/scenes/bedroom.toml:bedroom; do
    scene=${s%%:*}; name=${s##*:}
    "$w" render "$scene" --integrator bdpt --spp 2048 --size 128x128 --max-depth 8 -o "$out/$name-ref.exr"
    "$w" converge "$scene" --integrators lvc-mk,cis,lvc,bdpt,cis-nosort,path --seconds 8 --size 128x128 \
        --max-depth 8 --reference "$out/$name-ref.exr" -o "$out/run1/$name" > "$out/run1/$name.txt"
    "$w" converge "$scene" --integrators path,cis-nosort,bdpt,lvc,cis,lvc-mk --seconds 8 --size 128x128 \
        --max-depth 8 --reference "$out/$name-ref.exr" -o "$out/run2/$name" > "$out/run2/$name.txt"
done

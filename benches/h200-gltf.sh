#!/bin/bash
# The H200 measurements of issue 28, prepared for a session with a device machine. Put in the
# ignored .device/: tt (this build, stripped), tt-ref (the build to compare), DamagedHelmet.glb,
# helmet.toml (BENCHMARKS.md, issue 28), million.glb (benches/million.py); carry .gl and .device.
cd "$(dirname "$0")/.."
D=.device
T="/usr/bin/time -f %e_s_%M_KB"
nvidia-smi -L
$D/tt adapters 2>&1 | head -5
echo "== load (check: parse, buffers, decode, mapping, texture words)"
for f in tests/gltf/Box/Box.gltf tests/gltf/BoxTextured/BoxTextured.gltf $D/DamagedHelmet.glb $D/million.glb; do
  echo "-- $f"; $T $D/tt check $f 2>&1 | grep -E "objects|textures|_s_"
done
echo "== bench million (GPU)"
$T $D/tt bench $D/million.glb --width 1280 --height 720 --time 3 --warmup 1 2>&1 | grep -E "primitives|prepared|samples/s|segments/s|_s_|scene"
echo "== preview million"
$D/tt bench --preview $D/million.glb --presses 6 --timeout 10 2>&1 | grep -E "key|latenc|first|status line|traced"
echo "== helmet maps vs mean texels"
cd $D
for r in 1 2 3; do
  ./tt bench helmet.toml --width 1280 --height 720 --time 3 --warmup 1 2>&1 | grep -E "^samples/s|^scene|prepared" | sed "s/^/maps r$r: /"
  ./tt bench helmet.toml --width 1280 --height 720 --time 3 --warmup 1 --mean-textures 2>&1 | grep -E "^samples/s" | sed "s/^/mean r$r: /"
done
echo "== preview helmet"
./tt bench --preview helmet.toml --presses 8 --timeout 10 2>&1 | grep -E "key|latenc|first|traced"
cd ..
echo "== weekend 1920x1080 mb50: after / before"
for r in 1 2; do
  for b in tt tt-ref; do
    $D/$b bench weekend --width 1920 --height 1080 --max-bounces 50 --time 3 --warmup 1 2>&1 | grep -E "^samples/s|^segments/s" | tr '\n' ' ' | sed "s/^/$b r$r: /"; echo
  done
done

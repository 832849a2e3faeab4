#!/usr/bin/env bash
# bevy_cloth against bevy_silk 0.10 on the same cloth, in one run: a 1 m square of 64×64 particles
# hanging from two corners at 60 Hz, each crate with its default settings, one thread each
# (bevy_cloth: `cloth_cli bench` on `assets/scenes/silk_compare64.ron`, single-threaded executor,
# Bevy's static-scene transform tracking off, a compute pool of one thread; bevy_silk: `src/main.rs`
# here, built without Bevy's threads).
# Rounds alternate the two; the last lines give the medians over the rounds (time, and the median
# strain of the grid's rows and columns and of every constraint each crate has) and the ratio of
# bevy_silk's step alone to bevy_cloth's whole App frame.
#
#   compare/bevy_silk/run.sh [ROUNDS] [FRAMES]      (default 5 rounds of 600 timed frames)
set -euo pipefail
root="$(cd "$(dirname "$0")/../.." && pwd)"
rounds="${1:-5}"
frames="${2:-600}"

(cd "$root" && cargo build --release --example cloth_cli)
(cd "$root/compare/bevy_silk" && cargo build --release)

out="$(mktemp)"
trap 'rm -f "$out"' EXIT
for r in $(seq "$rounds"); do
    "$root/target/release/examples/cloth_cli" bench "$root/assets/scenes/silk_compare64.ron" \
        --frames "$frames" --threads 1 --single-threaded | sed 's/^/cloth /' | tee -a "$out"
    "$root/compare/bevy_silk/target/release/silk_compare" "$frames" | sed 's/^/silk /' | tee -a "$out"
done

python3 - "$out" <<'PY'
import json, statistics, sys
cloth, silk = [], []
for line in open(sys.argv[1]):
    who, _, rest = line.partition(" ")
    (cloth if who == "cloth" else silk).append(json.loads(rest))
med = lambda rows, key: statistics.median(r[key] for r in rows)
frame = med(cloth, "median_ms")
print(f"bevy_cloth whole App frame: median {frame:.3f} ms over {len(cloth)} rounds, "
      f"median strain of rows and columns {100 * med(cloth, 'median_structural_strain'):.3f}%, "
      f"shear {100 * med(cloth, 'median_shear_strain'):.3f}%, "
      f"bend {100 * med(cloth, 'median_bend_strain'):.3f}%, "
      f"all springs {100 * med(cloth, 'median_spring_strain'):.3f}%")
print(f"bevy_silk 0.10 whole App frame: {med(silk, 'app_frame_median_ms'):.3f} ms, "
      f"step alone: {med(silk, 'step_median_ms'):.3f} ms, "
      f"median strain of rows and columns {100 * med(silk, 'median_strain'):.3f}%, "
      f"all sticks {100 * med(silk, 'median_stick_strain'):.3f}%")
print(f"bevy_silk step alone / bevy_cloth whole frame: {med(silk, 'step_median_ms') / frame:.2f}")
print(f"bevy_silk whole frame / bevy_cloth whole frame: {med(silk, 'app_frame_median_ms') / frame:.2f}")
PY

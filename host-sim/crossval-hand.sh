#!/usr/bin/env bash
# Transfer in the board's context: leave one session out (host-sim/crossval.sh) with every
# calibration run's end pose measured as an operator measures it by hand, Gaussian noise of MM
# millimetres in x and y and MRAD milliradians in the heading (replay --end-noise), averaged over
# SEEDS draws (docs/calibration.md, "Transfer", "Heading weight and end offset").
#
#   bash host-sim/crossval-hand.sh [DATA_DIR [MM MRAD [SEEDS [REPLAY FLAGS...]]]]
#
# Defaults: ../shared/data, 2 mm and 14 mrad (a heading from the offsets of two points on the
# axle 200 mm apart, each measured to 2 mm), 20 seeds. Printed per calibration row and method:
# the mean over the seeds of the squares' and the other kinds' mean final position error (mm)
# and the standard deviation of the latter over the seeds.
set -euo pipefail
cd "$(dirname "$0")/.."
DATA=${1:-../shared/data}
MM=${2:-2}
MRAD=${3:-14}
SEEDS=${4:-20}
shift $(($# < 4 ? $# : 4))
for seed in $(seq 1 "$SEEDS"); do
  bash host-sim/crossval.sh "$DATA" --end-noise "$MM,$MRAD" --noise-seed "$seed" "$@" |
    awk -F'|' '/other final/ { t = 1 } t && /^\| from/ {
      m = $3; gsub(/ |\*|\(default\)/, "", m)
      row = ($2 ~ /squares/) ? "1.7 m squares" : "every other session"
      print row "|" m "|" $4 "|" $8 }'
done | awk -F'|' -v mm="$MM" -v mrad="$MRAD" -v seeds="$SEEDS" '
  { k = $1 "|" $2; n[k]++; sq[k] += $3; o[k] += $4; o2[k] += $4 * $4; if (!(k in seen)) { seen[k] = 1; order[++c] = k } }
  END {
    printf "End poses measured to %s mm / %s mrad (1σ), %s seeds; mean final position error, mm:\n\n", mm, mrad, seeds
    print "| calibrated on | method | squares | **other** | sd of other over seeds |"
    print "|---|---|---|---|---|"
    for (i = 1; i <= c; i++) {
      k = order[i]; split(k, f, "|"); m = o[k] / n[k]; v = o2[k] / n[k] - m * m
      printf "| %s | %s | %.2f | %.2f | %.2f |\n", f[1], f[2], sq[k] / n[k], m, sqrt(v > 0 ? v : 0)
    }
  }'

#!/usr/bin/env bash
# Cross-validation of every calibration method on the shared OptiOdom sessions, by session:
# calibrate on one set of sessions, evaluate on every other session (never on a calibration
# session). Prints a markdown table of the mean final position error per evaluated session (mm),
# with the uncalibrated (nominal) row and the in-sample floor (exact-path fitted on the very
# session it is evaluated on, to the truth as recorded that it is evaluated against). Needs jq.
#
#   bash host-sim/crossval.sh [DATA_DIR [REPLAY FLAGS...]]   # DATA_DIR default: ../shared/data
#
# REPLAY FLAGS go to every calibration (not to the nominal and floor rows), e.g. --from-start or
# --raw-truth to see what the start anchor or the heading offset changes.
set -euo pipefail
cd "$(dirname "$0")/.."
DATA=${1:-../shared/data}
shift || true
FLAGS=("$@")
D=$DATA/optiodom/diff
if [ ! -d "$D" ]; then
  echo "crossval: $D does not exist (give the folder that holds optiodom/ as the first argument)" >&2
  exit 2
fi
cargo build --release -q -p host-sim
SIM=${CARGO_TARGET_DIR:-target}/release/host-sim
if [ ! -x "$SIM" ]; then
  echo "crossval: $SIM was not built (CARGO_TARGET_DIR is relative to the repository root)" >&2
  exit 1
fi
OUT=$(mktemp -d)
trap 'rm -rf "$OUT"' EXIT

declare -A DIR=(
  [0029]=$D/square/231220200029 [0040]=$D/square/231220200040
  [2042]=$D/square/230620202042 [2144]=$D/square/230620202144
  [ivanjko]=$D/ivanjko/231220200057 [circle]=$D/circular/231220200134 [free]=$D/free/030120210001
)
EVAL=(0029 0040 2042 2144 ivanjko circle free)
# label | sessions
SETS=(
  "squares 1.7 m 0029|0029"
  "squares 1.7 m 0040|0040"
  "squares 1.7 m 0029+0040|0029 0040"
  "squares 0.75 m 2042+2144|2042 2144"
  "squares 1.7 m + lines (ivanjko)|0029 0040 ivanjko"
  "lines (ivanjko)|ivanjko"
  "circles|circle"
  "free paths|free"
)
id_of() { basename "${DIR[$1]}"; }
cell() { # json file, method, session key -> mm or "—"
  jq -r --arg m "$2" --arg s "$(id_of "$3")" \
    'select(.run=="all" and .method==$m) | .sessions[$s].final_pos_err_m // empty | . * 1000 | . * 10 | round / 10' "$1"
}
header="| calibrated on | method |"
sep="|---|---|"
for e in "${EVAL[@]}"; do header+=" $e |"; sep+="---|"; done
echo "$header"
echo "$sep"
# Nominal and floor rows.
all=()
for e in "${EVAL[@]}"; do all+=("${DIR[$e]}"); done
"$SIM" replay --evaluate "${all[@]}" --method nominal --format json --out "$OUT/n" > "$OUT/nominal.json" 2>/dev/null
row="| — | nominal |"
for e in "${EVAL[@]}"; do row+=" $(cell "$OUT/nominal.json" nominal "$e") |"; done
echo "$row"
row="| the evaluated session itself (in-sample floor) | exact-path |"
for e in "${EVAL[@]}"; do
  "$SIM" replay --calibrate "${DIR[$e]}" --evaluate "${DIR[$e]}" --method exact-path --raw-truth --from-start --format json --out "$OUT/f" > "$OUT/floor-$e.json" 2>/dev/null
  row+=" $(cell "$OUT/floor-$e.json" exact-path "$e") |"
done
echo "$row"
for s in "${SETS[@]}"; do
  label=${s%%|*}
  keys=(${s#*|})
  cal=(); ev=(); evk=()
  for k in "${keys[@]}"; do cal+=("${DIR[$k]}"); done
  for e in "${EVAL[@]}"; do
    [[ " ${keys[*]} " == *" $e "* ]] || { ev+=("${DIR[$e]}"); evk+=("$e"); }
  done
  f="$OUT/set.json"
  "$SIM" replay --calibrate "${cal[@]}" --evaluate "${ev[@]}" ${FLAGS[@]+"${FLAGS[@]}"} --format json --out "$OUT/s" > "$f" 2> "$OUT/set.err"
  for m in $(jq -r 'select(.run=="all" and .method!="nominal") | .method' "$f"); do
    tag=$m
    [ "$(jq -r --arg m "$m" 'select(.run=="all" and .method==$m) | .default' "$f")" = true ] && tag="**$m** (default)"
    row="| $label | $tag |"
    for e in "${EVAL[@]}"; do
      if [[ " ${keys[*]} " == *" $e "* ]]; then row+=" — |"; else row+=" $(cell "$f" "$m" "$e") |"; fi
    done
    echo "$row"
  done
  # An exact fit that the set cannot calibrate gets a row that says why (the closed forms are
  # missing wherever the set has no squares of one side and one belief, and need no row).
  sed -n 's/^\(exact[a-z-]*\): not calibrated on [^:]*: \(.*\)$/\1|\2/p' "$OUT/set.err" |
    while IFS='|' read -r m why; do
      echo "| $label | $m | not calibrated: $why |$(printf ' |%.0s' $(seq 2 ${#EVAL[@]}))"
    done
done

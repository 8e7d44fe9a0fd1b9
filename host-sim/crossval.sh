#!/usr/bin/env bash
# Transfer of every calibration method to the shared OptiOdom sessions it did not see: the
# measure that chooses the calibration defaults (docs/calibration.md, "Transfer").
#
#   bash host-sim/crossval.sh [DATA_DIR [REPLAY FLAGS...]]            # leave one session out
#   bash host-sim/crossval.sh --by-set [DATA_DIR [REPLAY FLAGS...]]   # the older table by set
#
# DATA_DIR (default ../shared/data) holds optiodom/. REPLAY FLAGS go to every calibration (not
# to the nominal row), e.g. --from-anchor, --channel-weights, --heading-apart, --heading-weight K,
# --raw-truth, --every-date,
# --scale-from lines|paths|never or --pool sessions. Needs jq.
#
# Leave one session out: every shared session in turn is evaluated (final position error and
# path RMS against the ground truth as recorded, from the recorded start), calibrated on
#  - "squares": the 1.7 m square sessions other than itself (the plan a user drives on the floor:
#    squares of one size; the closed forms need one side and one driving belief), and
#  - "every session": every other shared session given to replay, which calibrates with those
#    of them in the campaign nearest in time to the evaluated session (--every-date: with all).
#    The closed forms read squares of one side only: where the sessions mix sizes, their cells
#    repeat the squares row's.
# Printed: the cell per evaluated session (mean over its runs, mm), then the means by kind of
# session (squares, circles, lines = Ivanjko, free) and the mean over the kinds other than
# squares ("other"), for the final position error and the path RMS. The default (`"default":
# true` in replay's JSON) is marked.
#
# --by-set: calibrate on one set of sessions, evaluate on every other session; the cell is the
# mean final position error per evaluated session, with the nominal row and the in-sample floor.
set -euo pipefail
cd "$(dirname "$0")/.."
MODE=loo
if [ "${1:-}" = --by-set ]; then
  MODE=set
  shift
fi
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
SQUARES=(0029 0040)
id_of() { basename "${DIR[$1]}"; }

if [ "$MODE" = loo ]; then
  all=()
  for e in "${EVAL[@]}"; do all+=("${DIR[$e]}"); done
  "$SIM" replay --evaluate "${all[@]}" --method nominal --format json --out "$OUT/n" 2>/dev/null |
    jq -c 'select(.run != "all") | . + {row: "nominal"}' > "$OUT/runs.jsonl"
  for e in "${EVAL[@]}"; do
    sq=()
    for k in "${SQUARES[@]}"; do [ "$k" = "$e" ] || sq+=("${DIR[$k]}"); done
    every=()
    for k in "${EVAL[@]}"; do [ "$k" = "$e" ] || every+=("${DIR[$k]}"); done
    for row in squares every; do
      if [ "$row" = squares ]; then cal=("${sq[@]}"); else cal=("${every[@]}"); fi
      "$SIM" replay --calibrate "${cal[@]}" --evaluate "${DIR[$e]}" ${FLAGS[@]+"${FLAGS[@]}"} \
        --format json --out "$OUT/r" 2> "$OUT/err" |
        jq -c --arg row "$row" 'select(.run != "all" and .method != "nominal") | . + {row: $row}' \
          >> "$OUT/runs.jsonl"
    done
  done
  # Per (row, method, session): mean final error and path RMS over the runs; the every row's
  # closed forms (not calibrated on mixed square sizes) are taken from the squares row.
  jq -s -r '
    def mean: if length == 0 then null else add / length end;
    def mm: if . == null then "—" else . * 10000 | round / 10 | tostring end;
    def kindname: {"square": "squares", "circular": "circles", "ivanjko": "lines", "free": "free"}[.];
    . as $all
    | ([$all[] | select(.row != "nominal") | .method] | unique) as $methods
    | ([$all[] | select(.default == true) | .method] | unique) as $defaults
    | [$all[] | .session] as $order
    | ($order | reduce .[] as $s ([]; if index([$s]) then . else . + [$s] end)) as $sessions
    | def cells($row; $m):
        [ $sessions[] as $s
          | ([$all[] | select(.session == $s and .method == $m and .row == $row)]) as $r
          | (if ($r | length) == 0 and $row == "every"
              then [$all[] | select(.session == $s and .method == $m and .row == "squares")]
              else $r end) as $r
          | {session: $s, kind: ($r[0].kind // null),
             final: ([$r[].final_pos_err_m] | mean), rms: ([$r[].path_rms_m] | mean)} ];
      def bykind($c; $f):
        [ "squares", "circles", "lines", "free" ] as $kinds
        | [ $kinds[] as $k | [$c[] | select(.kind != null and (.kind | kindname) == $k) | .[$f]
            | select(. != null)] | mean ] as $km
        | $km + [ $km[1:] | map(select(. != null)) | mean ];
      def tag($m): if ($defaults | index([$m])) then "**\($m)** (default)" else $m end;
      ( [ ["squares", "from the 1.7 m squares alone (the other 1.7 m session for a 1.7 m square)"],
          ["every", "from every other session"] ] ) as $rows
      | "Final position error per evaluated session (mean over its runs, mm), each session calibrated without itself:",
        "",
        "| calibrated on | method | " + ($sessions | join(" | ")) + " |",
        "|---|---|" + ($sessions | map("---|") | join("")),
        ( "| — | nominal | " + ([cells("nominal"; "nominal")[] | .final | mm] | join(" | ")) + " |" ),
        ( $rows[] as [$row, $text] | $methods[] as $m
          | "| \($text) | \(tag($m)) | " + ([cells($row; $m)[] | .final | mm] | join(" | ")) + " |" ),
        "",
        "Means by kind of evaluated session (mm; each kind the mean of its sessions; other = the mean of circles, lines and free):",
        "",
        "| calibrated on | method | squares final | circles final | lines final | free final | **other final** | squares RMS | circles RMS | lines RMS | free RMS | other RMS |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
        ( "| — | nominal | " + (((bykind(cells("nominal"; "nominal"); "final")) + (bykind(cells("nominal"; "nominal"); "rms"))) | map(mm) | join(" | ")) + " |" ),
        ( $rows[] as [$row, $text] | $methods[] as $m | cells($row; $m) as $c
          | "| \($text) | \(tag($m)) | " + (((bykind($c; "final")) + (bykind($c; "rms"))) | map(mm) | join(" | ")) + " |" )
  ' "$OUT/runs.jsonl"
  # CROSSVAL_KEEP=FILE keeps the per-run lines (row, method, session, errors) for other summaries.
  [ -z "${CROSSVAL_KEEP:-}" ] || cp "$OUT/runs.jsonl" "$CROSSVAL_KEEP"
  exit 0
fi

# --by-set: label | sessions
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
  "$SIM" replay --calibrate "${DIR[$e]}" --evaluate "${DIR[$e]}" --method exact-path --raw-truth --format json --out "$OUT/f" > "$OUT/floor-$e.json" 2>/dev/null
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

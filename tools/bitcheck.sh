#!/usr/bin/env bash
# Checks that two cryofit binaries give byte-identical results: the three NBS nitrogen runs
# (examples/nbs/*.toml as they are: 30 cells, each compared with its measured data) and the quick
# NBS calibration (examples/nbs/calibrate-quick.toml, seed 7 as written in the file, 2 workers).
#
#   tools/bitcheck.sh OLD_BIN NEW_BIN [WORK_DIR]   runs both binaries into WORK_DIR/old and
#                                                  WORK_DIR/new (default: a temporary folder)
#                                                  and compares their outputs
#   tools/bitcheck.sh run BIN DIR                  only runs BIN, writing its outputs into DIR
#   tools/bitcheck.sh compare DIR_A DIR_B          only compares two folders written by `run`
#
# Compared byte for byte: for each simulation probes.csv, profiles.csv and summary.json; for the
# calibration result.json, best.toml, evaluations.csv, posterior.csv (when written) and every
# fit-*.csv. Left out, because they measure the wall clock or the process rather than the result:
#   - summary.json `wall_time_s` (the seconds the simulation took),
#   - result.json `wall_time_s` (the seconds the calibration took),
#   - calibration.sqlite (the coordinator's database: creation and update times, lease expiries,
#     worker names with process ids; the results it holds are those of the files above),
#   - what the commands print (it quotes the wall time too).
# The JSON files are compared with the line of each such top-level field deleted (the files are
# pretty-printed, one field a line) and every other byte kept. Exits 0 when everything matches,
# 1 on a difference, 2 on bad use.
set -euo pipefail
cd "$(dirname "$0")/.."

CASES=(saturated-2.5atm saturated-3.4atm subcooled-4.2atm)
CALIBRATION=examples/nbs/calibrate-quick.toml
# lines holding wall-clock times (top-level fields, indented by two spaces), per JSON file name
declare -A CLOCK_LINES=([summary.json]='^  "wall_time_s": ' [result.json]='^  "wall_time_s": ')

usage() {
    sed -n '2,22p' "$0" >&2
    exit 2
}

run_one() {
    local bin=$1 dir=$2
    [[ -x $bin ]] || { echo "bitcheck: $bin is not an executable" >&2; exit 2; }
    mkdir -p "$dir"
    for c in "${CASES[@]}"; do
        rm -rf "${dir:?}/$c"
        echo "bitcheck: $bin simulate $c" >&2
        "$bin" simulate "examples/nbs/$c.toml" --data "examples/nbs/$c-data.csv" --out "$dir/$c" >"$dir/$c.log"
    done
    rm -rf "${dir:?}/calibrate-quick"
    echo "bitcheck: $bin calibrate $(basename "$CALIBRATION")" >&2
    "$bin" calibrate "$CALIBRATION" --workers 2 --out "$dir/calibrate-quick" >"$dir/calibrate-quick.log"
}

# The files to compare in an output folder written by run_one, relative to it.
compared_files() {
    local dir=$1
    for c in "${CASES[@]}"; do
        printf '%s\n' "$c/probes.csv" "$c/profiles.csv" "$c/summary.json"
    done
    (cd "$dir" && ls calibrate-quick/result.json calibrate-quick/best.toml calibrate-quick/evaluations.csv \
        calibrate-quick/posterior.csv calibrate-quick/fit-*.csv 2>/dev/null || true)
}

compare() {
    local a=$1 b=$2 differ=0 n=0
    local files
    files=$( (compared_files "$a"; compared_files "$b") | sort -u)
    while IFS= read -r f; do
        n=$((n + 1))
        if [[ ! -f $a/$f || ! -f $b/$f ]]; then
            echo "bitcheck: DIFFERENT $f: missing in $([[ -f $a/$f ]] && echo "$b" || echo "$a")"
            differ=1
            continue
        fi
        local name filter
        name=$(basename "$f")
        filter=${CLOCK_LINES[$name]:-}
        if [[ -n $filter ]]; then
            if [[ $(grep -cE "$filter" "$a/$f") != 1 || $(grep -cE "$filter" "$b/$f") != 1 ]]; then
                echo "bitcheck: DIFFERENT $f: not exactly one line matching /$filter/"
                differ=1
            elif ! cmp -s <(grep -vE "$filter" "$a/$f") <(grep -vE "$filter" "$b/$f"); then
                echo "bitcheck: DIFFERENT $f (without the line /$filter/)"
                diff <(grep -vE "$filter" "$a/$f") <(grep -vE "$filter" "$b/$f") | head -20 || true
                differ=1
            else
                echo "bitcheck: same $f (without the line /$filter/)"
            fi
        elif ! cmp -s "$a/$f" "$b/$f"; then
            echo "bitcheck: DIFFERENT $f"
            diff "$a/$f" "$b/$f" | head -20 || true
            differ=1
        else
            echo "bitcheck: same $f"
        fi
    done <<<"$files"
    if [[ $differ == 0 ]]; then
        echo "bitcheck: all $n files identical"
    else
        echo "bitcheck: outputs differ"
    fi
    return $differ
}

case "${1:-}" in
    run) [[ $# == 3 ]] || usage; run_one "$2" "$3" ;;
    compare) [[ $# == 3 ]] || usage; compare "$2" "$3" ;;
    ""|-h|--help) usage ;;
    *)
        [[ $# == 2 || $# == 3 ]] || usage
        work=${3:-$(mktemp -d)}
        run_one "$1" "$work/old"
        run_one "$2" "$work/new"
        compare "$work/old" "$work/new"
        ;;
esac

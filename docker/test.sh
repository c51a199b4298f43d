#!/usr/bin/env bash
# Chaos test of the Compose deployment, on this machine's Docker engine (nothing is pulled).
#
#   docker/test.sh
#
# Builds the binary (cargo, on the host) and the image (docker/build-image.sh), runs the chaos
# calibration (docker/chaos/calibration.toml) once undisturbed with `cryofit calibrate` for the
# reference, then starts docker/compose.yaml with a coordinator and 3 workers, submits the same
# calibration and, while it runs: kills a worker container, cuts another off the network for
# longer than a lease and reconnects it, and restarts the coordinator container. Passes when the
# calibration completes with every parameter set costed exactly once (one counted result per
# experiment), evaluations equal to the budget, and the best cost and parameters bit-identical to
# the undisturbed run. Cleans up its containers, network and volume whatever happens; the last
# line is a one-line summary; exit code 0 only on success.
#
# Needs: a Docker engine that answers, python3, cargo. CRYOFIT_CHAOS_KEEP=1 keeps the work folder.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
repo="$(cd "$here/.." && pwd)"
started=$(date +%s)

LEASE_S=3
CUT_S=12              # longer than the lease: the cut-off worker's leases expire meanwhile
WORKERS=3
DEADLINE_S=1200       # for the whole disturbed calibration
calibration="$here/chaos/calibration.toml"
project="cryofit-chaos-$$"
work=$(mktemp -d "${TMPDIR:-/tmp}/cryofit-chaos.XXXXXX")
summary=""
phase="starting"

log() { echo "[$(($(date +%s) - started)) s] $*"; }
fail() {
    summary="docker/test.sh: FAIL after $(($(date +%s) - started)) s while $phase: $*"
    exit 1
}

compose() {
    docker compose -p "$project" -f "$here/compose.yaml" --env-file "$work/chaos.env" "$@"
}

cleanup() {
    local rc=$?
    trap - EXIT INT TERM
    if [ -f "$work/chaos.env" ]; then
        if [ "$rc" != 0 ]; then
            echo "----- container logs (last 40 lines each) -----"
            compose logs --no-color --tail 40 2>&1 || true
        fi
        compose down --volumes --remove-orphans --timeout 5 >"$work/down.log" 2>&1 || cat "$work/down.log"
    fi
    if [ "${CRYOFIT_CHAOS_KEEP:-0}" = 1 ]; then
        echo "work folder kept: $work"
    else
        rm -rf "$work"
    fi
    if [ -z "$summary" ]; then
        summary="docker/test.sh: FAIL after $(($(date +%s) - started)) s while $phase (exit code $rc)"
    fi
    echo "$summary"
    if [ "$rc" = 0 ] && [[ "$summary" != *PASS* ]]; then rc=1; fi
    exit "$rc"
}
trap cleanup EXIT
trap 'fail "interrupted"' INT TERM

# ---------------------------------------------------------------------------------------------
phase="checking the tools"
docker info >/dev/null 2>&1 || fail "no Docker engine answers 'docker info'"
command -v python3 >/dev/null || fail "python3 is needed"
"$here/setup.sh" >/dev/null || fail "docker/setup.sh could not provide 'docker compose'"

phase="building the binary"
(cd "$repo" && cargo build --release -p cryofit --quiet) || fail "cargo build failed"
bin="${CARGO_TARGET_DIR:-$repo/target}/release/cryofit"
[ -x "$bin" ] || fail "no binary at $bin"

phase="building the image"
log "building the image"
image_line=$("$here/build-image.sh" --binary "$bin" --tag cryofit:latest) || fail "docker/build-image.sh failed"
log "$image_line"
image_mib=$(docker image inspect -f '{{.Size}}' cryofit:latest | awk '{printf "%.1f", $1 / 1048576}')

# JSON helpers -------------------------------------------------------------------------------
client_token=$(od -An -N24 -tx1 /dev/urandom | tr -d ' \n')
worker_token=$(od -An -N24 -tx1 /dev/urandom | tr -d ' \n')
port=$(python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
url="http://127.0.0.1:$port"

# GET a JSON document of the coordinator (client token): `api PATH` prints it
api() {
    CRYOFIT_CHAOS_URL="$url" CRYOFIT_CHAOS_TOKEN="$client_token" python3 - "$1" <<'PY'
import json, os, sys, urllib.request
req = urllib.request.Request(os.environ["CRYOFIT_CHAOS_URL"] + sys.argv[1],
                             headers={"Authorization": "Bearer " + os.environ["CRYOFIT_CHAOS_TOKEN"]})
with urllib.request.urlopen(req, timeout=10) as r:
    sys.stdout.write(r.read().decode())
PY
}
# a field of the calibration, or "?" while the coordinator is away
field() {
    api "/api/v1/calibrations/$id" 2>/dev/null | python3 -c "import json, sys; print(json.load(sys.stdin)['$1'])" 2>/dev/null || echo "?"
}
# a metric without labels, or 0
metric() {
    python3 - "$url/metrics" "$1" <<'PY' 2>/dev/null || echo 0
import sys, urllib.request
text = urllib.request.urlopen(sys.argv[1], timeout=10).read().decode()
print(next((int(float(l.split()[1])) for l in text.splitlines() if l.startswith(sys.argv[2] + " ")), 0))
PY
}
# waits (bounded) until the calibration has at least $1 evaluations; fails if it ends first
wait_evaluations() {
    local want=$1 limit=$(($(date +%s) + 300)) n s
    while :; do
        n=$(field evaluations)
        s=$(field status)
        if [ "$s" != "?" ] && [ "$s" != running ] && [ "$s" != queued ]; then
            fail "the calibration ended ($s) before the disturbance at $want evaluations; make it longer"
        fi
        if [ "$n" != "?" ] && [ "$n" -ge "$want" ]; then return 0; fi
        [ "$(date +%s)" -lt "$limit" ] || fail "no progress to $want evaluations within 300 s (at $n)"
        sleep 0.5
    done
}
# waits (bounded) until at least $1 jobs are leased: a worker keeps at most twice its slots in
# hand, so with W one-slot workers, 2W-1 leased jobs mean every worker holds at least one
wait_leased() {
    leased_at_least "$1" 60 || fail "never saw $1 jobs leased at once within 60 s"
}
# whether at least $1 jobs are leased at once within $2 seconds
leased_at_least() {
    python3 - "$url/metrics" "$1" "$2" <<'PY'
import sys, time, urllib.request
deadline = time.monotonic() + float(sys.argv[3])
while time.monotonic() < deadline:
    try:
        text = urllib.request.urlopen(sys.argv[1], timeout=5).read().decode()
        if any(l.startswith("cryofit_leased_jobs ") and float(l.split()[1]) >= int(sys.argv[2]) for l in text.splitlines()):
            sys.exit(0)
    except OSError:
        pass
    time.sleep(0.02)
sys.exit(1)
PY
}
# waits (bounded) until the expired-leases counter exceeds $1; prints it
wait_expired() {
    local limit=$(($(date +%s) + LEASE_S + 10)) n
    while :; do
        n=$(metric cryofit_expired_leases_total)
        if [ "$n" -gt "$1" ]; then echo "$n"; return 0; fi
        [ "$(date +%s)" -lt "$limit" ] || { echo "$n"; return 1; }
        sleep 0.2
    done
}
container_of() { # the container of service $1, number $2
    docker ps -a -q --filter "label=com.docker.compose.project=$project" \
        --filter "label=com.docker.compose.service=$1" --filter "label=com.docker.compose.container-number=$2"
}
wait_healthy() {
    local c=$1 limit=$(($(date +%s) + 120)) h
    while :; do
        h=$(docker inspect -f '{{.State.Health.Status}}' "$c" 2>/dev/null || echo missing)
        [ "$h" = healthy ] && return 0
        [ "$(date +%s)" -lt "$limit" ] || fail "the coordinator container is $h after 120 s"
        sleep 0.5
    done
}

# ---------------------------------------------------------------------------------------------
phase="running the undisturbed reference"
log "undisturbed reference: cryofit calibrate $(basename "$calibration") on the host"
ref_started=$(date +%s)
"$bin" calibrate "$calibration" --workers 2 --out "$work/reference" >"$work/reference.log" 2>&1 \
    || { tail -20 "$work/reference.log"; fail "the reference calibration failed"; }
ref_s=$(($(date +%s) - ref_started))
log "reference done in $ref_s s"

phase="starting the coordinator and $WORKERS workers"
cat >"$work/chaos.env" <<EOF
CRYOFIT_CLIENT_TOKEN=$client_token
CRYOFIT_WORKER_TOKEN=$worker_token
CRYOFIT_PUBLISH=127.0.0.1:$port
CRYOFIT_LEASE_S=$LEASE_S
CRYOFIT_WORKER_SLOTS=1
CRYOFIT_IMAGE=cryofit:latest
EOF
log "docker compose up --scale worker=$WORKERS (project $project, coordinator on $url)"
# (not `up --wait`: Compose takes a service whose health check is disabled for one that failed)
compose up -d --scale "worker=$WORKERS" >"$work/up.log" 2>&1 \
    || { cat "$work/up.log"; fail "docker compose up failed"; }
coordinator=$(container_of coordinator 1)
[ -n "$coordinator" ] || fail "no coordinator container"
wait_healthy "$coordinator"
for k in $(seq 1 "$WORKERS"); do
    c=$(container_of worker "$k")
    [ -n "$c" ] || fail "no container for worker $k"
    [ "$(docker inspect -f '{{.State.Running}}' "$c")" = true ] || fail "worker $k is not running"
done
network="${project}_default"

phase="submitting"
id=$(CRYOFIT_TOKEN="$client_token" "$bin" submit "$calibration" --coordinator "$url" --json | tail -n 1 \
    | python3 -c 'import json, sys; print(json.load(sys.stdin)["id"])') || fail "cryofit submit failed"
budget=$(field budget)
log "submitted calibration $id (budget $budget evaluations)"

# the disturbances ----------------------------------------------------------------------------
# each disturbance waits until its victim holds leases, and checks that they expired
phase="killing a worker"
wait_evaluations $((budget * 15 / 100))
expired_before=$(metric cryofit_expired_leases_total)
wait_leased $((2 * WORKERS - 1))
victim=$(container_of worker 1)
docker kill "$victim" >/dev/null || fail "docker kill worker 1"
log "killed worker 1 at $(field evaluations) evaluations while it held leases"
# the victim may hand its jobs back between the lease count and the kill (then it holds none,
# and nothing expires): that is no fault; the cut-off worker below checks expiry for certain
if ! expired_kill=$(wait_expired "$expired_before"); then
    log "the killed worker held no lease when it died (it had handed its jobs back); nothing expired"
fi

phase="cutting a worker off the network"
wait_evaluations $((budget * 30 / 100))
cut=$(container_of worker 2)
# the victim may hand its jobs back between the lease count and the cut, and then hold none while
# the optimiser waits for its generation: cut off, it can hand nothing back, so a lease that
# expires while it is cut off is its own (the killed worker's have expired above, the other
# worker is connected); where none expires it held none, and it is connected again and cut off
# again. (The count of leased jobs right after the cut does not tell: with evaluations of a
# fraction of a second the other worker often holds one job, not two, and 2(W-1)-1 leased jobs
# were missed at five cuts in a row while the victim held its lease.)
expired_base=$expired_kill
for attempt in 1 2 3 4 5; do
    wait_leased $((2 * (WORKERS - 1) - 1))
    docker network disconnect "$network" "$cut" || fail "docker network disconnect worker 2"
    cut_until=$(($(date +%s) + CUT_S))
    if expired_cut=$(wait_expired "$expired_base"); then break; fi
    expired_base=$expired_cut
    docker network connect "$network" "$cut" || fail "docker network connect worker 2"
    [ "$attempt" -lt 5 ] || fail "worker 2 held no lease at any of 5 cuts (none expired within $((LEASE_S + 10)) s of each)"
    log "no lease expired within $((LEASE_S + 10)) s of cutting worker 2 off (it had handed its jobs back); connected again"
done
log "cut worker 2 off at $(field evaluations) evaluations for $CUT_S s (lease $LEASE_S s); its leases expired"
while [ "$(date +%s)" -lt "$cut_until" ]; do sleep 0.5; done
docker network connect "$network" "$cut" || fail "docker network connect worker 2"
log "reconnected worker 2 at $(field evaluations) evaluations; $((expired_cut - expired_base)) of its leases had expired"

phase="restarting the coordinator"
wait_evaluations $((budget * 55 / 100))
expired_total=$(metric cryofit_expired_leases_total)
stale_total=$(metric cryofit_stale_results_total)
docker restart --time 10 "$coordinator" >/dev/null || fail "docker restart coordinator"
log "restarted the coordinator"
wait_healthy "$coordinator"
log "coordinator healthy again at $(field evaluations) evaluations"

phase="waiting for the calibration to complete"
limit=$(($(date +%s) + DEADLINE_S))
while :; do
    s=$(field status)
    if [ "$s" != "?" ] && [ "$s" != running ] && [ "$s" != queued ]; then break; fi
    [ "$(date +%s)" -lt "$limit" ] || fail "not complete within $DEADLINE_S s (at $(field evaluations) evaluations)"
    sleep 1
done
[ "$s" = completed ] || fail "the calibration ended $s: $(api "/api/v1/calibrations/$id")"
expired_total=$((expired_total + $(metric cryofit_expired_leases_total)))
stale_total=$((stale_total + $(metric cryofit_stale_results_total)))
log "completed; coordinator memory $(docker stats --no-stream --format '{{.MemUsage}}' "$coordinator" 2>/dev/null || echo unknown)"

# the checks ----------------------------------------------------------------------------------
phase="checking the history"
api "/api/v1/calibrations/$id" >"$work/calibration.json"
for what in parameter-sets results; do
    offset=0
    : >"$work/$what.jsonl"
    for _ in $(seq 1 1000); do
        api "/api/v1/calibrations/$id/$what?limit=500&offset=$offset" >"$work/page.json"
        python3 - "$work/page.json" >>"$work/$what.jsonl" <<'PY'
import json, sys
for item in json.load(open(sys.argv[1]))["items"]:
    print(json.dumps(item))
PY
        offset=$(python3 -c 'import json, sys; n = json.load(open(sys.argv[1]))["next_offset"]; print("" if n is None else n)' "$work/page.json")
        [ -n "$offset" ] || break
    done
done
verdict=$(python3 - "$work" <<'PY'
import json, sys
from collections import Counter
work = sys.argv[1]
cal = json.load(open(f"{work}/calibration.json"))
ref = json.load(open(f"{work}/reference/result.json"))
sets = [json.loads(l) for l in open(f"{work}/parameter-sets.jsonl")]
results = [json.loads(l) for l in open(f"{work}/results.jsonl")]
problems = []
experiments = len(cal.get("experiments") or []) or len({r["experiment_id"] for r in results})
if cal["evaluations"] != cal["budget"]:
    problems.append(f"evaluations {cal['evaluations']} != budget {cal['budget']}")
if len(sets) != cal["budget"]:
    problems.append(f"{len(sets)} parameter sets for a budget of {cal['budget']}")
# a parameter set whose simulation fails is an outcome, not a fault, as long as the undisturbed
# run met the same number of them (the calibration is deterministic)
failed = [s["id"] for s in sets if s["status"] == "failed"]
not_ok = [s["id"] for s in sets if s["status"] not in ("ok", "failed")]
if not_ok:
    problems.append(f"parameter sets neither ok nor failed: {not_ok[:10]}")
if len(failed) != ref.get("failed_evaluations", 0):
    problems.append(f"{len(failed)} failed parameter sets {failed[:10]}, the undisturbed run had {ref.get('failed_evaluations')}")
counted = Counter((r["parameter_set_id"], r["experiment_id"]) for r in results if r["status"] != "stale")
stale = sum(1 for r in results if r["status"] == "stale")
lost = [s["id"] for s in sets if any(counted[(s["id"], e)] == 0 for e in {r["experiment_id"] for r in results})]
twice = sorted({k[0] for k, n in counted.items() if n > 1})
if lost:
    problems.append(f"parameter sets without a counted result: {lost[:10]}")
if twice:
    problems.append(f"parameter sets counted more than once: {twice[:10]}")
for s in sets:
    parts = [r for r in results if r["parameter_set_id"] == s["id"] and r["status"] != "stale"]
    if s["status"] == "failed":
        if s["cost"] is not None or not any(r["status"] == "failed" for r in parts):
            problems.append(f"failed parameter set {s['id']}: cost {s['cost']}, results {[r['status'] for r in parts]}")
            break
        continue
    total = sum(r["cost"] for r in parts) if all(r.get("cost") is not None for r in parts) else None
    if total is None or s["cost"] is None or abs(total - s["cost"]) > 1e-9 * max(1.0, abs(s["cost"])):
        problems.append(f"parameter set {s['id']}: cost {s['cost']} != sum of its results {total}")
        break
if cal["best_cost"] != ref["best_cost"]:
    problems.append(f"best cost {cal['best_cost']!r} != undisturbed {ref['best_cost']!r}")
if cal["best_parameters"] != ref["best_parameters"]:
    problems.append(f"best parameters {cal['best_parameters']} != undisturbed {ref['best_parameters']}")
if problems:
    print("FAIL " + "; ".join(problems))
else:
    print(f"OK {cal['evaluations']} {cal['budget']} {len(sets)} {stale} {cal['best_cost']!r} {len(results)}")
PY
)
case "$verdict" in
    OK*) ;;
    *) fail "${verdict#FAIL }" ;;
esac
read -r _ evaluations budget sets stale best results_n <<<"$verdict"
elapsed=$(($(date +%s) - started))
phase="done"
summary="docker/test.sh: PASS in $elapsed s: calibration $id completed $evaluations/$budget evaluations, all $sets parameter sets costed exactly once (0 lost, 0 twice; $stale stale results discarded, $expired_total leases expired), best cost $best bit-identical to the undisturbed run; survived 3 disruptions (worker killed, worker cut off ${CUT_S} s > ${LEASE_S} s lease, coordinator restarted); image ${image_mib} MiB"

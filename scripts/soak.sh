#!/usr/bin/env bash
# Soak test of the separate-process runtime, run by hand (not in CI): many short IPC runs
# across both master algorithms and every wait strategy, half of them with two CPU hogs
# running, a few at a time. Every completed run's timeseries.csv is compared byte for byte
# with the in-process run of the same settings. Prints the counts (completed, hung, failed,
# differing) and the repair of lost samples (re-sent requests, lost requests and replies) and
# exits non-zero on any hung, failed or differing run, or on shared-memory files left behind.
#
#   scripts/soak.sh [--bin PATH] [--runs N] [--jobs J] [--duration S] [--scenario FILE]
#                   [--out DIR] [--limit SECONDS]
#
# Defaults: the release build's tiltsim, 2000 runs, 3 at a time, 2 s simulated,
# scenarios/paper-lqg.toml, a fresh directory under /tmp; a run counts as hung after 300 s
# without progress (its participants' status words unchanged), as slow when it took longer
# but progressed.
set -u

here=$(cd "$(dirname "$0")/.." && pwd)
bin="$here/target/release/tiltsim"
runs=2000
jobs=3
duration=2
scenario="$here/scenarios/paper-lqg.toml"
out=""
limit=300
while [ $# -gt 0 ]; do
  case "$1" in
    --bin) bin=$2; shift 2 ;;
    --runs) runs=$2; shift 2 ;;
    --jobs) jobs=$2; shift 2 ;;
    --duration) duration=$2; shift 2 ;;
    --scenario) scenario=$2; shift 2 ;;
    --out) out=$2; shift 2 ;;
    --limit) limit=$2; shift 2 ;;
    -h|--help) sed -n '2,13p' "$0"; exit 0 ;;
    *) echo "soak.sh: unknown argument $1 (see --help)" >&2; exit 2 ;;
  esac
done
[ -x "$bin" ] || { echo "soak.sh: $bin is not an executable tiltsim" >&2; exit 2; }
[ -f "$scenario" ] || { echo "soak.sh: no scenario $scenario" >&2; exit 2; }
out=${out:-$(mktemp -d /tmp/tiltsim-soak.XXXXXX)}
mkdir -p "$out/runs"
results="$out/results.txt"
: > "$results"
tag="soak$$"

masters=(gauss-seidel jacobi)
waits=(adaptive sleep spin paced)

# The reference series: one in-process run per master (the wait strategy changes no value).
for m in "${masters[@]}"; do
  if ! "$bin" run "$scenario" --transport in-process --master "$m" --duration "$duration" \
      --out "$out/ref-$m" -q 2>"$out/ref-$m.err"; then
    echo "soak.sh: the in-process reference run ($m) failed:" >&2
    cat "$out/ref-$m.err" >&2
    exit 1
  fi
done

hogs=()
stop_hogs() {
  for p in "${hogs[@]}"; do kill "$p" 2>/dev/null; done
  hogs=()
}
trap 'stop_hogs; exit 130' INT TERM
trap 'stop_hogs' EXIT

# One run: appends "index master wait hogs outcome resends lost_requests lost_replies".
one() {
  local i=$1 m=$2 w=$3 h=$4
  local d="$out/runs/$i"
  local pfx="${tag}_${i}_"
  "$bin" run "$scenario" --transport ipc --master "$m" --wait "$w" \
    --duration "$duration" --ipc-prefix "$pfx" --out "$d" -q >/dev/null 2>"$d.err" &
  local pid=$! rc
  # Hung means no progress: the participants' status words (the exchange each last took and
  # answered) unchanged for $limit s. A run that progresses, however slowly (a spinning wait
  # on an oversubscribed machine), is waited for and counted slow past $limit s.
  local seen="" since=$SECONDS started=$SECONDS killed=0
  while kill -0 "$pid" 2>/dev/null; do
    sleep 1
    local now
    now=$(cat /dev/shm/"${pfx}"status_* 2>/dev/null | cksum)
    if [ "$now" != "$seen" ]; then seen=$now; since=$SECONDS; fi
    if [ $((SECONDS - since)) -ge "$limit" ]; then kill -KILL "$pid"; killed=1; break; fi
  done
  wait "$pid"
  rc=$?
  local outcome
  if [ $killed -eq 1 ]; then
    outcome=hung
    # What nobody cleans up after a SIGKILL: the participants follow the orchestrator.
    sleep 1
    "$bin" clean >/dev/null 2>&1
  elif [ $rc -eq 0 ] && [ $((SECONDS - started)) -ge "$limit" ] \
      && cmp -s "$d/timeseries.csv" "$out/ref-$m/timeseries.csv"; then
    outcome=slow
  elif [ $rc -ne 0 ]; then
    outcome=failed
  elif cmp -s "$d/timeseries.csv" "$out/ref-$m/timeseries.csv"; then
    outcome=completed
  else
    outcome=differing
  fi
  local counts="0 0 0"
  if [ -f "$d/perf.json" ]; then
    counts=$(python3 - "$d/perf.json" <<'PY'
import json, sys
p = json.load(open(sys.argv[1]))["participants"]
t = [sum(v.get("lost_samples", {}).get(k, 0) for v in p.values())
     for k in ("resends", "lost_requests", "lost_replies")]
print(*t)
PY
)
  fi
  echo "$i $m $w $h $outcome $counts" >> "$results"
  # Keep what explains a bad run; a good one only takes space.
  if [ "$outcome" = completed ] || [ "$outcome" = slow ]; then rm -rf "$d" "$d.err"; fi
}

# Blocks of 50 runs, quiet and under two CPU hogs in turn: half the runs each, and a soak
# stopped early still has both.
block=50
for ((i = 0; i < runs; i++)); do
  if [ $((i % block)) -eq 0 ]; then
    wait
    stop_hogs
    phase=quiet
    if [ $(((i / block) % 2)) -eq 1 ]; then
      phase=hogs
      # Not jobs of this shell: `jobs` counts runs only, `wait` waits for runs only.
      for _ in 1 2; do
        yes > /dev/null &
        hogs+=($!)
        disown $!
      done
    fi
  fi
  m=${masters[$((i % 2))]}
  w=${waits[$(((i / 2) % 4))]}
  one "$i" "$m" "$w" "$phase" &
  while [ "$(jobs -rp | wc -l)" -ge "$jobs" ]; do wait -n; done
  if [ $(((i + 1) % 100)) -eq 0 ]; then
    echo "$(date -u +%H:%M:%S) $((i + 1)) of $runs started; $(awk '{c[$5]++} END {for (k in c) printf "%s %d  ", k, c[k]}' "$results")"
  fi
done
wait
stop_hogs

left=$(find /dev/shm /tmp/iceoryx2 -maxdepth 5 -name "${tag}_*" 2>/dev/null | wc -l)
count() { awk -v o="$1" '$5 == o' "$results" | wc -l; }
completed=$(count completed)
hung=$(count hung)
slow=$(count slow)
failed=$(count failed)
differing=$(count differing)
read -r resends lreq lrep <<<"$(awk '{r += $6; q += $7; p += $8} END {print r + 0, q + 0, p + 0}' "$results")"
echo
echo "soak: $(wc -l < "$results") IPC runs of $(basename "$scenario"), --duration $duration, $jobs at a time, half with two CPU hogs (blocks of 50)"
echo "  completed $completed (of them slow, past ${limit} s: $slow)  hung $hung  failed $failed  differing $differing"
echo "  re-sent requests $resends (lost requests $lreq, lost replies $lrep)"
awk '{k = $2 " " $3 " " $4; n[k]++; if ($5 == "completed" || $5 == "slow") c[k]++; r[k] += $6}
     END {for (k in n) printf "    %-28s %4d runs, %4d completed, %3d re-sent\n", k, n[k], c[k], r[k]}' \
  "$results" | sort
echo "  shared-memory entries left: $left"
echo "  details: $results (bad runs kept under $out/runs)"
bad=$((hung + failed + differing + left))
[ "$bad" -eq 0 ]

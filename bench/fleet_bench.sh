#!/usr/bin/env bash
# The ground station at fleet scale (BENCHMARKS.md, "Ground station at fleet scale"): for each N, a
# synthetic fleet (odonav-bench-fleet-publisher: N vehicles' DR at 10 Hz, estimates and health at
# 1 Hz, one process) against `odonav-ground serve`, with the fleet page open in headless chromium
# and one Foxglove client subscribed to every channel. Measures the ground station's CPU (utime +
# stime over the measuring window, from /proc) and memory (VmHWM), the delay from a DDS sample to its
# WebSocket frame at the client (p50/p99), and how long after fleet-000's identification falls
# silent its DiagnosticArray shows STALE.
# Usage: bench/fleet_bench.sh [N ...]   (default: 10 50 200). Run under scripts/isolated or any host
# where domain 189 is free; loopback only.
# Environment: ODONAV_BUILD_DIR (odonav-ground; default build), ODONAV_BENCH_BUILD_DIR
# (odonav-bench-fleet-publisher; default build-bench), ODONAV_WEB_NPM (node_modules with
# @foxglove/ws-protocol ws @foxglove/rosmsg @foxglove/rosmsg2-serialization puppeteer-core; default
# <build>/tests/ground-web-npm/node_modules, where the ground_web test installs them).
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build=${ODONAV_BUILD_DIR:-$root/build}
bench_build=${ODONAV_BENCH_BUILD_DIR:-$root/build-bench}
export NODE_PATH=${ODONAV_WEB_NPM:-$build/tests/ground-web-npm/node_modules}
profile=$root/deploy/profiles/loopback.xml
domain=189
work=$(mktemp -d)
sizes=("$@")
[[ ${#sizes[@]} -eq 0 ]] && sizes=(10 50 200)
duration=60      # publisher run (s)
warmup=10        # client and CPU window start (s)
window=30        # CPU window (s)
silence=45       # fleet-000's identification falls silent (s)
pids=()
cleanup() { for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done; fastdds shm clean >/dev/null 2>&1 || true; rm -rf "$work"; }
trap cleanup EXIT
ticks() { awk '{print $14 + $15}' "/proc/$1/stat"; }
hz=$(getconf CLK_TCK)
printf '%-5s %-9s %-9s %-9s %-9s %-9s %-10s %-8s %-9s\n' N cpu_% vmhwm_MiB p50_ms p99_ms max_ms frames_s page_rows stale_s
for n in "${sizes[@]}"; do
  fastdds shm clean >/dev/null 2>&1 || true
  "$build/bin/odonav-ground" serve --domain $domain --profile "$profile" --port 0 --log-level warn >"$work/serve.out" 2>"$work/serve.err" &
  serve=$!; pids+=("$serve")
  for _ in $(seq 100); do grep -q 'http://127.0.0.1:' "$work/serve.out" 2>/dev/null && break; sleep 0.1; done
  port=$(sed -n 's|.*http://127.0.0.1:\([0-9]*\)/.*|\1|p' "$work/serve.out")
  "$bench_build/bin/odonav-bench-fleet-publisher" --vehicles "$n" --domain $domain --profile "$profile" \
    --duration-s $duration --silence-after-s $silence >"$work/pub.out" 2>"$work/pub.err" &
  pub=$!; pids+=("$pub")
  node "$root/bench/fleet_page.js" "$port" $((duration - 5)) >"$work/page.out" 2>"$work/page.err" &
  page=$!; pids+=("$page")
  node "$root/bench/fleet_client.js" "$port" $((duration - 2)) $warmup >"$work/client.out" 2>"$work/client.err" &
  client=$!; pids+=("$client")
  sleep $warmup
  t0=$(ticks "$serve"); sleep $window; t1=$(ticks "$serve")
  wait "$client" "$page" "$pub" || true
  hwm=$(awk '/VmHWM/ {print $2}' "/proc/$serve/status")
  kill -INT "$serve"; wait "$serve" || true
  python3 - "$n" "$t0" "$t1" "$hz" "$window" "$hwm" "$work" "$duration" "$warmup" <<'PY'
import json, sys
n, t0, t1, hz, window, hwm, work, duration, warmup = sys.argv[1:]
c = json.loads(open(f"{work}/client.out").read())
page = json.loads(open(f"{work}/page.out").read())
silenced = [float(l.split()[-1]) for l in open(f"{work}/pub.out") if l.startswith("silenced at")]
stale = (c["stale_at_unix_s"] - silenced[0]) if c["stale_at_unix_s"] and silenced else None
cpu = 100.0 * (int(t1) - int(t0)) / int(hz) / float(window)
d = c["delay_ms"]
fmt = lambda v: "-" if v is None else f"{v:.1f}"
rate = c["frames"] / (float(duration) - 2 - float(warmup))
print(f"{n:<5} {cpu:<9.1f} {int(hwm)/1024:<9.1f} {fmt(d['p50']):<9} {fmt(d['p99']):<9} {fmt(d['max']):<9} {rate:<10.0f} {page.get('rows', page.get('error')):<8} {fmt(stale):<9}")
PY
  pids=()
done

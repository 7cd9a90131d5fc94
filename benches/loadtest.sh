#!/usr/bin/env bash
# Load-test figures for docs/BENCHMARKS.md ("Service under load"): starts the
# release service on the bundled config and scenes, then runs bmc-loadtest
# for every scenario and client count, sampling the server's RSS.
#
#   bash benches/loadtest.sh [DURATION] [PORT]     # default 15s, 8391
set -euo pipefail
cd "$(dirname "$0")/.."
duration=${1:-15s}
port=${2:-8391}
cargo build --release --quiet
bin=target/release/bmc-irradiance
$bin serve --bind "127.0.0.1:$port" 2>/tmp/bmc-loadtest-server.log &
server=$!
trap 'kill $server 2>/dev/null || true' EXIT
for _ in $(seq 50); do curl -sf "http://127.0.0.1:$port/health" >/dev/null && break; sleep 0.2; done
# A health answer from some other process on the port would be no use.
kill -0 $server || { echo "the server did not start:"; cat /tmp/bmc-loadtest-server.log; exit 1; }
echo "machine: nproc=$(nproc), $(lscpu | grep 'Model name' | sed 's/ \+/ /g')"
for scenario in points tiles mixed; do
  for clients in 1 8 64 256; do
    echo "== scenario=$scenario clients=$clients duration=$duration"
    target/release/bmc-loadtest --url "http://127.0.0.1:$port" --clients "$clients" --duration "$duration" \
      --scenario "$scenario" --server-pid "$server" 2>&1 | grep -v '^ '
  done
done

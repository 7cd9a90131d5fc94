#!/usr/bin/env bash
# A local cluster on loopback: N bmc-irradiance replicas sharing one Redis,
# behind HAProxy.
#
#   deploy/local-cluster.sh up [N]   # start Redis, N replicas (default 3) and HAProxy; prints the URL
#   deploy/local-cluster.sh status   # what is running
#   deploy/local-cluster.sh down     # stop everything
#
# Run from the repository root (it serves the bundled scenes/). Replicas
# listen on 127.0.0.1:18081.. , HAProxy on 127.0.0.1:18080, Redis on
# 127.0.0.1:18079 (nothing kept on disk); each replica keeps its tile log
# and posted scenes in .cluster/replica-K/. Installs Debian's haproxy and
# redis-server when missing (as root). Logs and pid files are in .cluster/.
# ROUND_ROBIN=1 replaces routing by scene with round robin (for comparison).
set -euo pipefail
cd "$(dirname "$0")/.."
STATE=.cluster
FRONT=127.0.0.1:18080
BASE_PORT=18081
REDIS_PORT=18079

up() {
    local n=${1:-3}
    local missing=()
    command -v haproxy >/dev/null || missing+=(haproxy)
    command -v redis-server >/dev/null || missing+=(redis-server)
    if [ ${#missing[@]} -gt 0 ]; then
        apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${missing[@]}" >/dev/null
    fi
    cargo build --release --quiet
    mkdir -p "$STATE"
    redis-server --port "$REDIS_PORT" --bind 127.0.0.1 --save "" --appendonly no \
        >"$STATE/redis.log" 2>&1 &
    echo $! >"$STATE/redis.pid"
    local servers=""
    # One secret for this cluster's replicas: they refuse what Redis holds unsigned.
    local secret
    secret="$(head -c 24 /dev/urandom | od -An -tx1 | tr -d ' \n')"
    for k in $(seq 1 "$n"); do
        local port=$((BASE_PORT + k - 1))
        mkdir -p "$STATE/replica-$k"
        BMC_CACHE__DATA_DIR="$STATE/replica-$k" NO_COLOR=1 \
            BMC_CLUSTER__REDIS_URL="redis://127.0.0.1:$REDIS_PORT/0" BMC_CLUSTER__SECRET="$secret" \
            target/release/bmc-irradiance serve --bind "127.0.0.1:$port" \
            >"$STATE/replica-$k.log" 2>&1 &
        echo $! >"$STATE/replica-$k.pid"
        servers+="    server r$k 127.0.0.1:$port check"$'\n'
    done
    local balance=""
    [ "${ROUND_ROBIN:-0}" = 1 ] && balance='s|balance hash path,field(4,/)|balance roundrobin|'
    sed -e "s|@FRONTEND@|$FRONT|" -e "$balance" deploy/haproxy.cfg.in |
        awk -v servers="$servers" '{ if ($0 == "@SERVERS@") printf "%s", servers; else print }' \
        >"$STATE/haproxy.cfg"
    haproxy -f "$STATE/haproxy.cfg" -db >"$STATE/haproxy.log" 2>&1 &
    echo $! >"$STATE/haproxy.pid"
    for _ in $(seq 1 100); do
        curl -sf "http://$FRONT/health" >/dev/null && break
        sleep 0.2
    done
    echo "http://$FRONT/ ($n replicas sharing Redis 127.0.0.1:$REDIS_PORT, behind HAProxy)"
}

status() {
    for pid in "$STATE"/*.pid; do
        [ -e "$pid" ] || { echo "nothing running"; return; }
        local name; name=$(basename "$pid" .pid)
        if kill -0 "$(cat "$pid")" 2>/dev/null; then echo "$name: running"; else echo "$name: stopped"; fi
    done
}

down() {
    for pid in "$STATE"/*.pid; do
        [ -e "$pid" ] || continue
        kill "$(cat "$pid")" 2>/dev/null || true
        rm -f "$pid"
    done
    echo "stopped"
}

case "${1:-}" in
    up) up "${2:-3}" ;;
    status) status ;;
    down) down ;;
    *) echo "usage: $0 up [N] | status | down" >&2; exit 2 ;;
esac

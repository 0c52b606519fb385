#!/usr/bin/env bash
# Emulate a second host on this machine for fulcrum's multihost runs: a network
# namespace joined to this one by a veth pair, whose processes also get their own
# /dev/shm and /tmp (where iceoryx2 keeps its files), so nothing is shared with this
# host but the link.
#
#   scripts/two-hosts.sh up             create the namespace and the link
#   scripts/two-hosts.sh exec CMD...    run CMD as the other host
#   scripts/two-hosts.sh cut SECS       take the link down for SECS seconds, then up again
#   scripts/two-hosts.sh down           remove the namespace and the link
#   scripts/two-hosts.sh demo [STEPS]   a learner here and an actor host there, with a
#                                       20 s cut mid-run (needs a multihost build)
#   scripts/two-hosts.sh bench          the BENCHMARKS.md figures: `bench --remote` against
#                                       a peer there, and training steps/s with one actor
#                                       host here (learner + 1 actor) and one there
#
# This host is 10.213.$FULCRUM_NET.1, the other 10.213.$FULCRUM_NET.2 (FULCRUM_NET
# defaults to 7; the namespace is $FULCRUM_NETNS, default fulcrum-b). Needs root and
# iproute2.
set -euo pipefail

NET=${FULCRUM_NET:-7}
NS=${FULCRUM_NETNS:-fulcrum-b}
A=fva-$NET
B=fvb-$NET
HERE=10.213.$NET.1
THERE=10.213.$NET.2

die() { echo "two-hosts.sh: $*" >&2; exit 2; }
# The secret of the run in directory $1, once its bridge has written it.
run_secret() {
  for _ in $(seq 600); do [ -s "$1/secret" ] && break; sleep 0.1; done
  cut -d: -f2 "$1/secret"
}
[ "$(id -u)" = 0 ] || die "needs root (network namespaces)"
command -v ip >/dev/null || die "needs iproute2 (ip)"

case "${1:-}" in
  up)
    ip netns add "$NS"
    ip link add "$A" type veth peer name "$B"
    ip link set "$B" netns "$NS"
    ip addr add "$HERE/30" dev "$A"
    ip link set "$A" up
    ip -n "$NS" addr add "$THERE/30" dev "$B"
    ip -n "$NS" link set "$B" up
    ip -n "$NS" link set lo up
    ;;
  exec)
    shift
    [ $# -gt 0 ] || die "exec needs a command"
    # The program's own directory is bound outside /tmp first: a program that lives
    # under /tmp (a clone there) would vanish under the new /tmp, and it starts its
    # children from its own path.
    exec ip netns exec "$NS" unshare --mount --propagation private sh -c \
      'prog=$(readlink -f "$1") && shift &&
       mkdir -p /run/fulcrum-far-bin && mount --bind "$(dirname "$prog")" /run/fulcrum-far-bin &&
       mount -t tmpfs -o mode=1777 tmpfs /dev/shm && mount -t tmpfs -o mode=1777 tmpfs /tmp &&
       exec "/run/fulcrum-far-bin/$(basename "$prog")" "$@"' \
      sh "$@"
    ;;
  cut)
    secs=${2:?cut needs seconds}
    ip link set "$A" down
    sleep "$secs"
    ip link set "$A" up
    ;;
  down)
    ip link del "$A" 2>/dev/null || true
    ip netns del "$NS" 2>/dev/null || true
    ;;
  demo)
    steps=${2:-3000000}
    bin=${FULCRUM_BIN:-target/release/fulcrum}
    out=${FULCRUM_DEMO_OUT:-runs/two-hosts-demo}
    "$0" down
    "$0" up
    trap '"$0" down' EXIT
    rm -rf "$out"
    "$bin" train exp2 --listen "$HERE:7447" --steps "$steps" --out "$out" \
      --stall-timeout 2 --session-timeout 3 &
    learner=$!
    sleep 2
    FULCRUM_SECRET=$(run_secret "$out") \
      "$0" exec "$bin" actor-host --connect "$HERE:7447" --name far --session-timeout 3 \
      --dir /tmp/far &
    host=$!
    sleep 20
    echo "two-hosts.sh: cutting the link for 20 s"
    "$0" cut 20
    echo "two-hosts.sh: link up again"
    wait "$learner"
    wait "$host" || true
    echo "per-host chunks: $out/hosts.csv"
    ;;
  bench)
    bin=${FULCRUM_BIN:-target/release/fulcrum}
    out=${FULCRUM_DEMO_OUT:-runs/two-hosts-bench}
    steps=${2:-1228800}
    "$0" down
    "$0" up
    trap '"$0" down; kill $(jobs -p) 2>/dev/null || true' EXIT
    # The peer listens beyond loopback, so both ends present a secret of their own.
    FULCRUM_SECRET=$(od -An -tx1 -N32 /dev/urandom | tr -d ' \n')
    export FULCRUM_SECRET
    "$0" exec "$bin" __remote-peer --listen "$THERE:7448" > /dev/null &
    sleep 3
    "$bin" bench --remote "$THERE:7448" --json "${FULCRUM_BENCH_JSON:-/dev/null}"
    median() { # column 15 (sps) of metrics rows whose remote_actors (23) is $2, skipping update 1
      awk -F, -v k="$2" 'NR > 2 && $23 == k { print $15 }' "$1" | sort -g |
        awk '{ v[NR] = $1 } END { if (NR) printf "%.0f steps/s (median of %d updates)", v[int((NR + 1) / 2)], NR }'
    }
    rm -rf "$out" "$out-alone"
    "$bin" train exp2 --actors 1 --steps "$steps" --out "$out-alone" > /dev/null 2>&1
    "$bin" train exp2 --actors 1 --listen "$HERE:7447" --steps "$steps" --out "$out" > /dev/null 2>&1 &
    learner=$!
    sleep 1
    FULCRUM_SECRET=$(run_secret "$out") \
      "$0" exec "$bin" actor-host --connect "$HERE:7447" --name far --actors 1 --dir /tmp/far \
      > /dev/null 2>&1 &
    wait "$learner"
    echo "training env steps/s, train exp2 --actors 1 (8 worlds x 128 steps a chunk):"
    echo "  learner host alone:                          $(median "$out-alone/metrics.csv" 0)"
    echo "  with an actor host (1 actor) in the other namespace: $(median "$out/metrics.csv" 1)"
    ;;
  *)
    sed -n '2,23p' "$0" | sed 's/^# \{0,1\}//'
    exit 2
    ;;
esac

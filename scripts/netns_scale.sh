#!/usr/bin/env bash
# DDS across "hosts" on one machine: two network namespaces joined by a veth pair, skin_sim_node
# in one, device bridge + simulated Touch + latency observer in the other; the same scene with
# everything in one namespace for comparison. Needs root and iproute2 (exit 77 = skipped).
#
#   bash scripts/netns_scale.sh [DURATION_S]           as root (default 20 s per case; about 4 x that in all)
#   sudo bash scripts/netns_scale.sh [DURATION_S]      the same from a user account that has sudo
#   CASES="cross_udp" ...                               (subset of: same_udp cross_udp same_shm cross_default)
#
# Discovery across the veth: ROS_AUTOMATIC_DISCOVERY_RANGE=SUBNET (Fast DDS multicast SPDP on
# 239.255.0.1, so each namespace gets a multicast route on its veth end). Data: UDPv4 only
# (FASTDDS_BUILTIN_TRANSPORTS=UDPv4), as between real hosts; Fast DDS would otherwise use shared
# memory, which network namespaces on one host still share. Namespaces are removed on exit.
set -euo pipefail
cd "$(dirname "$0")/.."
if [ "${1:-}" = "-h" ] || [ "${1:-}" = "--help" ]; then
  sed -n '2,12p' "$0" | sed 's/^# \{0,1\}//'; exit 0
fi
DURATION="${1:-20}"
PY="${PY:-$PWD/.venv/bin/python}"
if [ "$(id -u)" != 0 ]; then
  if command -v sudo >/dev/null; then how="sudo bash scripts/netns_scale.sh $DURATION"; else how="as root: bash scripts/netns_scale.sh $DURATION"; fi
  echo "netns_scale: skipped: needs root (ip netns); run it $how"; exit 77
fi
echo "netns_scale: as root (uid 0); cases ${CASES:-same_udp cross_udp same_shm cross_default}, ${DURATION} s each"
if ! command -v ip >/dev/null; then echo "netns_scale: skipped: needs iproute2 (ip)"; exit 77; fi

TAG="$$"
NS_SIM="ssim_sim_$TAG"; NS_DEV="ssim_dev_$TAG"
V_SIM="ssvs$TAG"; V_DEV="ssvd$TAG"    # interface names: at most 15 characters
OUT="$(mktemp -d /tmp/skin_sim_netns_XXXXXX)"
PIDS=()

cleanup() {
  for p in "${PIDS[@]:-}"; do [ -n "$p" ] && kill -TERM "$p" 2>/dev/null || true; done
  for p in "${PIDS[@]:-}"; do [ -n "$p" ] && wait "$p" 2>/dev/null || true; done
  ip netns del "$NS_SIM" 2>/dev/null || true
  ip netns del "$NS_DEV" 2>/dev/null || true
}
trap cleanup EXIT
trap 'exit 130' INT TERM

if ! ip netns add "$NS_SIM" 2>"$OUT/err"; then
  echo "netns_scale: skipped: cannot create network namespaces: $(cat "$OUT/err")"; exit 77
fi
ip netns add "$NS_DEV"
ip link add "$V_SIM" type veth peer name "$V_DEV"
ip link set "$V_SIM" netns "$NS_SIM"
ip link set "$V_DEV" netns "$NS_DEV"
ip -n "$NS_SIM" addr add 10.231.0.1/24 dev "$V_SIM"
ip -n "$NS_DEV" addr add 10.231.0.2/24 dev "$V_DEV"
for ns_if in "$NS_SIM:$V_SIM" "$NS_DEV:$V_DEV"; do
  ns="${ns_if%%:*}"; dev="${ns_if##*:}"
  ip -n "$ns" link set lo up
  ip -n "$ns" link set "$dev" up
  ip -n "$ns" route add 224.0.0.0/4 dev "$dev"   # multicast discovery leaves through the veth
done
echo "netns_scale: $NS_SIM (10.231.0.1) <-veth-> $NS_DEV (10.231.0.2); $DURATION s per case; logs $OUT"

DOMAIN="${ROS_DOMAIN_ID:-$((60 + RANDOM % 40))}"
run_case() {  # label sim_ns dev_ns transports
  local label="$1" sim_ns="$2" dev_ns="$3" transports="$4" log="$OUT/node_$5.log"
  local envs=(env ROS_DOMAIN_ID="$DOMAIN" ROS_AUTOMATIC_DISCOVERY_RANGE=SUBNET ROS_LOG_DIR="$OUT/ros" PYTHONUNBUFFERED=1)
  [ "$transports" != DEFAULT ] && envs+=(FASTDDS_BUILTIN_TRANSPORTS="$transports")
  ip netns exec "$sim_ns" "${envs[@]}" "$PY" -m skin_sim_node.cli node --ros-args --params-file config/default.yaml >"$log" 2>&1 &
  local sim=$!
  PIDS+=("$sim")
  for _ in $(seq 600); do grep -q "live:" "$log" && break; kill -0 "$sim" 2>/dev/null || { cat "$log"; return 1; }; sleep 0.2; done
  ip netns exec "$dev_ns" "${envs[@]}" "$PY" -m skin_sim_node.cli netns-role device \
    --duration-s "$DURATION" --label "$label" --json "$OUT/$5.json"
  kill -TERM "$sim"; wait "$sim" || true
}
declare -A LABEL=([same_udp]="same namespace, UDPv4" [cross_udp]="across namespaces (veth), UDPv4"
                   [same_shm]="same namespace, default (SHM)" [cross_default]="across namespaces, default transports")
declare -A SIM_NS=([same_udp]="$NS_DEV" [cross_udp]="$NS_SIM" [same_shm]="$NS_DEV" [cross_default]="$NS_SIM")
declare -A TRANSPORTS=([same_udp]=UDPv4 [cross_udp]=UDPv4 [same_shm]=DEFAULT [cross_default]=DEFAULT)
JSONS=()
for c in ${CASES:-same_udp cross_udp same_shm}; do
  run_case "${LABEL[$c]}" "${SIM_NS[$c]}" "$NS_DEV" "${TRANSPORTS[$c]}" "$c"
  JSONS+=("$OUT/$c.json")
done
"$PY" -m skin_sim_node.cli netns-role compare "${JSONS[@]}"

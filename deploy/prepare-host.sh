#!/usr/bin/env bash
# Prepares a host for LCM streaming (server, capture node or viewer).
#   deploy/prepare-host.sh --check   say what is wrong; exit 0 when nothing is, 1 otherwise
#   deploy/prepare-host.sh --apply   fix it (root): UDP receive buffer, multicast route
# Checks:
#   rmem     net.core.rmem_max >= the receive buffer the LCM URL asks for (4 MB: a 640x480 frame is
#            ~75 KB compressed, a mesh up to a few MB; the kernel default 208 KB drops them)
#   mcast    a route for multicast (224.0.0.0/4): LCM's udpm transport needs one; on a host with
#            only loopback up, the route goes to lo
#   lo-mcast the loopback interface accepts multicast (needed when the route goes to lo)
set -u
mode=${1:---check}
want_rmem=${VDEFORM_RMEM:-4194304}
case "$mode" in
  --check | --apply) ;;
  -h | --help)
    sed -n '2,11p' "$0" | sed 's/^# \{0,1\}//'
    exit 0
    ;;
  *)
    echo "prepare-host: unknown mode '$mode' (--check or --apply)" >&2
    exit 2
    ;;
esac
problems=0
report() {  # name, ok(0/1), message
  if [ "$2" = 0 ]; then echo "OK   $1: $3"; else echo "FIX  $1: $3"; problems=$((problems + 1)); fi
}

rmem=$(cat /proc/sys/net/core/rmem_max 2>/dev/null || echo 0)
if [ "$rmem" -ge "$want_rmem" ]; then
  report rmem 0 "net.core.rmem_max = $rmem >= $want_rmem"
elif [ "$mode" = --apply ]; then
  if sysctl -q -w net.core.rmem_max="$want_rmem" >/dev/null 2>&1; then
    report rmem 0 "net.core.rmem_max set to $want_rmem (persist it in /etc/sysctl.d/60-vdeform.conf)"
  else
    report rmem 1 "net.core.rmem_max = $rmem < $want_rmem and could not be raised (run as root)"
  fi
else
  report rmem 1 "net.core.rmem_max = $rmem < $want_rmem: sysctl -w net.core.rmem_max=$want_rmem"
fi

route=$(ip -4 route show 224.0.0.0/4 2>/dev/null; ip -4 route show default 2>/dev/null)
up_non_lo=$(ip -o -4 addr show up 2>/dev/null | awk '$2 != "lo"' | wc -l)
if [ -n "$route" ]; then
  report mcast 0 "multicast goes by: $(echo "$route" | head -1)"
elif [ "$mode" = --apply ]; then
  dev=lo
  [ "$up_non_lo" -gt 0 ] && dev=$(ip -o -4 addr show up | awk '$2 != "lo" {print $2; exit}')
  if ip route add 224.0.0.0/4 dev "$dev" 2>/dev/null; then
    report mcast 0 "added route 224.0.0.0/4 dev $dev"
  else
    report mcast 1 "no multicast route and could not add one on $dev (run as root)"
  fi
else
  dev=lo
  [ "$up_non_lo" -gt 0 ] && dev="<your LAN interface>"
  report mcast 1 "no route for 224.0.0.0/4 (nor a default route): ip route add 224.0.0.0/4 dev $dev"
fi

if ip -o -4 route show 224.0.0.0/4 2>/dev/null | grep -q "dev lo"; then
  if ip link show lo | grep -q MULTICAST; then
    report lo-mcast 0 "lo accepts multicast"
  elif [ "$mode" = --apply ] && ip link set lo multicast on 2>/dev/null; then
    report lo-mcast 0 "multicast turned on for lo"
  else
    report lo-mcast 1 "the multicast route uses lo but lo has no MULTICAST flag: ip link set lo multicast on"
  fi
fi

[ "$problems" -eq 0 ] && exit 0
exit 1

#!/usr/bin/env bash
# Prepares a host for LCM streaming (server, capture node or viewer).
#   deploy/prepare-host.sh --check   say what is wrong; exit 0 when nothing is, 1 otherwise
#   deploy/prepare-host.sh --apply   fix it (root): UDP receive buffer, multicast route
#   ... --dev IFACE                  multi-host: multicast must leave by IFACE (the LAN interface)
# Checks:
#   rmem     net.core.rmem_max >= the receive buffer the LCM URL asks for (4 MB: a 640x480 frame is
#            ~75 KB compressed, a mesh up to a few MB; the kernel default 208 KB drops them)
#   mcast    a route for multicast (224.0.0.0/4): LCM's udpm transport needs one; on a host with
#            only loopback up, the route goes to lo
#   lo-mcast the loopback interface accepts multicast (needed when the route goes to lo)
#   mcast-dev with --dev: the LCM group 239.255.76.67 is routed out of IFACE; without --dev, a
#            warning when $LCM_DEFAULT_URL asks for ttl >= 1 (multi-host) but multicast goes to lo
set -u
mode=--check
want_dev=""
while [ $# -gt 0 ]; do
  case "$1" in
    --check | --apply) mode=$1; shift ;;
    --dev) want_dev=${2:?--dev needs an interface}; shift 2 ;;
    -h | --help)
      sed -n '2,14p' "$0" | sed 's/^# \{0,1\}//'
      exit 0
      ;;
    *)
      echo "prepare-host: unknown argument '$1' (--check, --apply, --dev IFACE)" >&2
      exit 2
      ;;
  esac
done
want_rmem=${VDEFORM_RMEM:-4194304}
group=239.255.76.67
if [ -n "$want_dev" ] && ! ip link show "$want_dev" >/dev/null 2>&1; then
  echo "prepare-host: no interface '$want_dev'" >&2
  exit 2
fi
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
if [ -n "$want_dev" ]; then
  : # checked below (mcast-dev)
elif [ -n "$route" ]; then
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

out_dev=$(ip -4 route get "$group" 2>/dev/null | sed -n 's/.* dev \([^ ]*\).*/\1/p' | head -1)
if [ -n "$want_dev" ]; then
  if [ "$out_dev" = "$want_dev" ]; then
    report mcast-dev 0 "$group leaves by $want_dev"
  elif [ "$mode" = --apply ] && ip route replace 224.0.0.0/4 dev "$want_dev" 2>/dev/null; then
    report mcast-dev 0 "route 224.0.0.0/4 dev $want_dev set (was: ${out_dev:-none}; persist it in the network configuration)"
  else
    report mcast-dev 1 "$group leaves by ${out_dev:-nothing}, not $want_dev: ip route replace 224.0.0.0/4 dev $want_dev"
  fi
elif [ "$out_dev" = lo ] && echo "${LCM_DEFAULT_URL:-}" | grep -Eq 'ttl=[1-9]'; then
  report mcast-dev 1 "LCM_DEFAULT_URL asks for ttl>=1 (multi-host) but multicast goes to lo: rerun with --dev <LAN interface>"
fi

[ "$problems" -eq 0 ] && exit 0
exit 1

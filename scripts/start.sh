#!/usr/bin/env bash
# Quick-start command 1: install what is missing, build, and start `cutload serve` on
# 127.0.0.1:8080 with the bundled demo dry runs already submitted (the first demo, and the second:
# a multi-tool inch program with its tool table), so the first thing a new user sees is finished
# runs. Prints an admin API key and the URLs. Ctrl-C stops the service
# gracefully. Safe to run again: the database, key and demo run are reused.
#
# Environment: CUTLOAD_LISTEN (127.0.0.1:8080), CUTLOAD_STATE_DIR (build/serve),
#              CUTLOAD_BUILD_DIR (build), CUTLOAD_DEVICE (opencl).
set -euo pipefail
cd "$(dirname "$0")/.."

CUTLOAD_TARGETS="cutload cutload_web" scripts/setup.sh

BUILD_DIR=${CUTLOAD_BUILD_DIR:-build}
BIN=$BUILD_DIR/cli/cutload
LISTEN=${CUTLOAD_LISTEN:-127.0.0.1:8080}
STATE_DIR=${CUTLOAD_STATE_DIR:-$BUILD_DIR/serve}
DB=$STATE_DIR/cutload.db
KEY_FILE=$STATE_DIR/admin.key
URL=http://$LISTEN
LOG=data/demo_dryrun.csv
SPEC=data/demo_run.json
NC=data/demo_program.nc
# The second demo: three tools (face mill, end mill, drill), an inch program without G20 or G90.1.
LOG2=data/demo2_dryrun.csv
SPEC2=data/demo2_run.json
NC2=data/demo2_program.nc
NC2_OPTIONS='{"program_units": "in", "arc_centers": "absolute"}'
# The five-axis demo: a ring groove cut by turning the C table of the bundled AC machine (data/README.md).
LOG3=data/demo3_dryrun.csv
SPEC3=data/demo3_run.json
NC3=data/demo3_program.nc
MACHINE3=data/machines/ac_table_table.json
NC3_OPTIONS='{"work_offsets_mm": {"G54": [-350, -275, -460]}}'
# The 3+2 demo: the same machine's table indexed to A-20, a ball-end mill finishing with its axis leaning 20 deg.
LOG4=data/demo4_dryrun.csv
SPEC4=data/demo4_run.json
NC4=data/demo4_program.nc
NC4_OPTIONS='{"work_offsets_mm": {"G54": [-350, -275, -560]}}'

for f in "$LOG" "$SPEC" "$NC" "$LOG2" "$SPEC2" "$NC2" "$LOG3" "$SPEC3" "$NC3" "$MACHINE3" "$LOG4" "$SPEC4" "$NC4"; do
  [ -f "$f" ] || { echo "cutload start: $f is missing from this checkout" >&2; exit 1; }
done
mkdir -p "$STATE_DIR"

# The key is only shown once by `keys create`; keep it (owner-only) so a second start can reuse it.
if [ ! -s "$KEY_FILE" ]; then
  (umask 077; "$BIN" keys create --role admin --db "$DB" --name quick-start | tail -n 1 > "$KEY_FILE")
fi
KEY=$(cat "$KEY_FILE")

"$BIN" serve --listen "$LISTEN" --db "$DB" --web "$BUILD_DIR/web/site" --anonymous-loopback-reads \
  --device "${CUTLOAD_DEVICE:-opencl}" &
SERVER=$!
# Whatever ends this script (Ctrl-C, a failed request under set -e) stops the service gracefully.
stop_server() { kill -TERM "$SERVER" 2>/dev/null && wait "$SERVER" 2>/dev/null; true; }
trap stop_server EXIT
trap 'exit 130' INT TERM

for _ in $(seq 1 100); do
  curl -fsS "$URL/healthz" >/dev/null 2>&1 && break
  kill -0 $SERVER 2>/dev/null || { echo "cutload start: the service did not start (is $LISTEN in use?)" >&2; exit 1; }
  sleep 0.1
done

api() { curl -fsS -H "Authorization: Bearer $KEY" "$@"; }
# The first "key": value in a JSON answer (ids are numbers, states are plain words).
json_field() { { grep -o "\"$1\": *\"\{0,1\}[A-Za-z0-9_]*" || true; } | head -n 1 | sed 's/.*: *"\{0,1\}//'; }

RUN=$(api "$URL/api/v1/runs?program=demo&limit=1" | json_field id)
if [ -z "$RUN" ]; then
  echo "cutload start: submitting the demo dry run ($LOG) with its NC program ($NC)"
  RUN=$(api -F "log=@$LOG" -F "spec=<$SPEC" -F "nc_program=@$NC" -F name=demo -F program=demo "$URL/api/v1/runs" | json_field id)
fi
RUN2=$(api "$URL/api/v1/runs?program=demo2&limit=1" | json_field id)
if [ -z "$RUN2" ]; then
  echo "cutload start: submitting the multi-tool demo ($LOG2) with its NC program ($NC2) and tool table ($SPEC2)"
  RUN2=$(api -F "log=@$LOG2" -F "spec=<$SPEC2" -F "nc_program=@$NC2" -F "nc_options=$NC2_OPTIONS" \
    -F name=demo2 -F program=demo2 "$URL/api/v1/runs" | json_field id)
fi
RUN3=$(api "$URL/api/v1/runs?program=demo3&limit=1" | json_field id)
if [ -z "$RUN3" ]; then
  echo "cutload start: submitting the five-axis demo ($LOG3) with its machine ($MACHINE3) and NC program ($NC3)"
  RUN3=$(api -F "log=@$LOG3" -F "spec=<$SPEC3" -F "kinematics=@$MACHINE3" -F "nc_program=@$NC3" \
    -F "nc_options=$NC3_OPTIONS" -F name=demo3 -F program=demo3 "$URL/api/v1/runs" | json_field id)
fi
RUN4=$(api "$URL/api/v1/runs?program=demo4&limit=1" | json_field id)
if [ -z "$RUN4" ]; then
  echo "cutload start: submitting the 3+2 demo ($LOG4): the table indexed, a tilted ball-end mill, with its NC program ($NC4)"
  RUN4=$(api -F "log=@$LOG4" -F "spec=<$SPEC4" -F "kinematics=@$MACHINE3" -F "nc_program=@$NC4" \
    -F "nc_options=$NC4_OPTIONS" -F name=demo4 -F program=demo4 "$URL/api/v1/runs" | json_field id)
fi
wait_run() {
  local state
  while :; do
    state=$(api "$URL/api/v1/runs/$1" | json_field state)
    case "$state" in
      queued|running) sleep 0.5 ;;
      *) echo "$state"; return ;;
    esac
  done
}
STATE=$(wait_run "$RUN")
STATE2=$(wait_run "$RUN2")
STATE3=$(wait_run "$RUN3")
STATE4=$(wait_run "$RUN4")

cat <<EOF

cutload is running at $URL  (Ctrl-C stops it)
  demo run $RUN: $STATE
  multi-tool demo run $RUN2: $STATE2 ($URL/#/runs/$RUN2)
  five-axis demo run $RUN3: $STATE3 ($URL/#/runs/$RUN3)
  3+2 demo run $RUN4: $STATE4 ($URL/#/runs/$RUN4)
  web page:         $URL/
  the run:          $URL/api/v1/runs/$RUN
  per-block loads:  $URL/api/v1/runs/$RUN/blocks
  forces (plot):    $URL/api/v1/runs/$RUN/forces?max_points=2000
  program vs actual: $URL/api/v1/runs/$RUN/program
  API description:  $URL/api/v1/openapi.json
  metrics:          $URL/metrics
Reads from this machine need no key. For writes, the admin key (kept in $KEY_FILE):
  $KEY
e.g. curl -H "Authorization: Bearer $KEY" -F log=@$LOG -F "spec=<$SPEC" -F nc_program=@$NC $URL/api/v1/runs
EOF

wait $SERVER

#!/usr/bin/env bash
# A throw-away PostgreSQL cluster for tests and benchmarks (docs/deploy.md, "How the tests get a
# cluster"):
#   scripts/pg_test_cluster.sh start DIR [PORT]   initdb in DIR, start postgres, print the URL
#   scripts/pg_test_cluster.sh stop DIR           stop it and remove DIR
#   scripts/pg_test_cluster.sh url DIR            print the URL of a started cluster
# The server listens on a unix socket in DIR only (no TCP port: nothing to collide with other
# clusters or services, and the URL is known before it starts); PORT (default 5432) only names
# the socket. Superuser "cutload", trust authentication (the socket is reachable from this
# machine only, and DIR is the invoking user's). Durability is off (fsync, full-page writes): the
# data is thrown away. initdb refuses to run as root: as root the cluster is run by "nobody".
# Server binaries: $PG_BINDIR, else PATH, else the newest /usr/lib/postgresql/*/bin (Debian).
set -euo pipefail

die() { echo "pg_test_cluster: $*" >&2; exit 1; }

find_bindir() {
  if [[ -n "${PG_BINDIR:-}" ]]; then
    [[ -x "$PG_BINDIR/initdb" && -x "$PG_BINDIR/pg_ctl" ]] || die "PG_BINDIR=$PG_BINDIR holds no initdb and pg_ctl"
    echo "$PG_BINDIR"; return
  fi
  if command -v initdb >/dev/null && command -v pg_ctl >/dev/null; then
    dirname "$(readlink -f "$(command -v initdb)")"; return
  fi
  local d
  for d in $(ls -d /usr/lib/postgresql/*/bin 2>/dev/null | sort -V -r); do
    [[ -x "$d/initdb" && -x "$d/pg_ctl" ]] && { echo "$d"; return; }
  done
  return 1
}

# The socket directory as the URL's host, '/' percent-encoded: no '?' or '&' in the URL, so it
# passes through a shell command line unquoted.
url_of() { echo "postgresql://cutload@${1//\//%2F}:$2/postgres"; }

cmd=${1:-}; dir=${2:-}
[[ -n "$cmd" && -n "$dir" ]] || die "usage: $0 start|stop|url DIR [PORT]"
port=${3:-5432}

# As root the cluster belongs to an unprivileged user, and every server command runs as that user.
as_owner=()
if [[ $(id -u) -eq 0 ]]; then
  owner=${CUTLOAD_PG_TEST_USER:-nobody}
  as_owner=(runuser -u "$owner" --)
fi

case "$cmd" in
  start)
    bindir=$(find_bindir) || die "no PostgreSQL server binaries (initdb, pg_ctl) on PATH or in /usr/lib/postgresql/*/bin; install Debian's 'postgresql' package"
    # A unix socket path holds at most 107 bytes.
    (( ${#dir} <= 80 )) || die "$dir: path too long for a unix socket directory (80 characters at most)"
    if [[ -f "$dir/data/postmaster.pid" ]]; then
      "${as_owner[@]}" "$bindir/pg_ctl" -D "$dir/data" -m immediate stop >/dev/null 2>&1 || true
    fi
    rm -rf "$dir"
    mkdir -p "$dir"
    [[ ${#as_owner[@]} -eq 0 ]] || chown "$owner" "$dir"
    chmod 700 "$dir"
    "${as_owner[@]}" "$bindir/initdb" -D "$dir/data" -U cutload -A trust -E UTF8 --no-sync --locale=C >"$dir/initdb.log" 2>&1 \
      || { cat "$dir/initdb.log" >&2; die "initdb failed (log above)"; }
    # Tests run two at a time, each server with a few pooled connections (HTTP threads, workers).
    opts="-c listen_addresses='' -c unix_socket_directories='$dir' -c port=$port -c max_connections=300"
    opts+=" -c fsync=off -c synchronous_commit=off -c full_page_writes=off -c shared_buffers=64MB"
    "${as_owner[@]}" "$bindir/pg_ctl" -D "$dir/data" -l "$dir/server.log" -o "$opts" -w -t 60 start >/dev/null \
      || { cat "$dir/server.log" >&2; die "postgres did not start (log above)"; }
    url_of "$dir" "$port" | tee "$dir/url"
    ;;
  stop)
    if [[ -f "$dir/data/postmaster.pid" ]]; then
      bindir=$(find_bindir) || die "no PostgreSQL server binaries to stop $dir with"
      "${as_owner[@]}" "$bindir/pg_ctl" -D "$dir/data" -m fast -w stop >/dev/null || die "pg_ctl stop failed for $dir"
    fi
    rm -rf "$dir"
    ;;
  url)
    [[ -f "$dir/url" ]] || die "no cluster started in $dir"
    cat "$dir/url"
    ;;
  *) die "unknown command '$cmd' (start, stop or url)" ;;
esac

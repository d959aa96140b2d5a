#!/usr/bin/env bash
# Install Debian's PostgreSQL and start a cluster on 127.0.0.1:55432 with a dms role.
set -euo pipefail
if ! command -v pg_createcluster >/dev/null 2>&1; then
  apt-get update -qq
  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq postgresql >/dev/null
fi
version=$(ls /usr/lib/postgresql | sort -n | tail -1)
if ! pg_lsclusters -h | awk '{print $2}' | grep -qx dmsci; then
  pg_createcluster "$version" dmsci -p 55432 -- --auth-local=trust --auth-host=md5 >/dev/null
fi
sed -i "s/^#\?listen_addresses.*/listen_addresses = '127.0.0.1'/" "/etc/postgresql/$version/dmsci/postgresql.conf"
pg_ctlcluster "$version" dmsci start || true
su postgres -c "psql -p 55432 -qtc \"SELECT 1 FROM pg_roles WHERE rolname='dms'\"" | grep -q 1 \
  || su postgres -c "psql -p 55432 -qc \"CREATE ROLE dms LOGIN PASSWORD 'dms' CREATEDB\""
su postgres -c "psql -p 55432 -qtc \"SELECT 1 FROM pg_database WHERE datname='dms_test'\"" | grep -q 1 \
  || su postgres -c "psql -p 55432 -qc 'CREATE DATABASE dms_test OWNER dms'"
echo "ci: PostgreSQL $version on 127.0.0.1:55432"

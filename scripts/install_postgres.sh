#!/usr/bin/env bash
# Install Debian's PostgreSQL server binaries (needed by tests/test_optimize.py, which starts a throwaway server on
# loopback for the distributed Optuna test). Does nothing when they are already there.
set -euo pipefail
if ls /usr/lib/postgresql/*/bin/initdb >/dev/null 2>&1; then
    exit 0
fi
if [ "$(id -u)" -ne 0 ]; then
    echo "PostgreSQL server binaries are missing: run this script as root (sudo bash scripts/install_postgres.sh)." >&2
    exit 1
fi
export DEBIAN_FRONTEND=noninteractive
apt-get update -q
apt-get install -y -q --no-install-recommends postgresql

#!/usr/bin/env bash
# Installs the Debian packages the package needs and builds it in a catkin workspace.
set -euo pipefail
source "$(dirname "$0")/common.sh"
aloam_install_deps
aloam_build "$@"
aloam_log "built: source $ALOAM_WS/devel/setup.bash"

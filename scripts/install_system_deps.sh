#!/usr/bin/env bash
# Debian packages the project needs: a C/C++ toolchain (flip_msgs generation, the compiled tick and
# step), GL libraries for offscreen rendering (MuJoCo with MUJOCO_GL=egl or osmesa) and Debian's
# python3.11 with venv and headers, the interpreter of the project's venv (Makefile, PY_BOOT); iproute2
# (ss) and util-linux (unshare) for the sweep tests' loopback checks.
# Installs only what is missing.
set -euo pipefail
need=()
for pkg in g++ make libegl1 libgl1 libosmesa6 python3.11 python3.11-venv python3.11-dev iproute2 util-linux; do
  dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null | grep -q "install ok installed" || need+=("$pkg")
done
[ ${#need[@]} -eq 0 ] && exit 0
echo "installing Debian packages: ${need[*]}"
SUDO=""; [ "$(id -u)" -eq 0 ] || SUDO="sudo"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${need[@]}"

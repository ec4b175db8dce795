# Neptunus — the two commands that matter: `make run` and `make test`.
# Everything else is what they depend on. `make setup` is idempotent.

SHELL := /bin/bash
.DEFAULT_GOAL := help

APT_PACKAGES := elixir erlang-dev erlang-src erlang-yaws erlang-jiffy erlang-proper \
                erlang-dialyzer socat chromium gcc libc6-dev python3 python3-venv openssl \
                ffmpeg
YAWS_DIR := $(firstword $(wildcard /usr/lib/yaws-*))
ASSETS_STAMP := assets/node_modules/.package-lock.json
# pymavlink and MAVProxy (the MAVLink interoperability tests) and mcap (the MCAP reader the
# dive exports are checked with), test-only, in a project-local virtualenv. MAVProxy without
# its optional dependencies (maps, consoles, plots: ~1 GB, none of it used headless); pyserial
# is the one it imports at start.
PYMAVLINK_VERSION := 2.4.50
MAVPROXY_VERSION := 1.8.75
PYSERIAL_VERSION := 3.5
MCAP_VERSION := 1.6.0
VENV_STAMP := .venv/.pymavlink-$(PYMAVLINK_VERSION)-mavproxy-$(MAVPROXY_VERSION)-mcap-$(MCAP_VERSION)

.PHONY: help setup setup-apt setup-links setup-npm setup-venv assets compile run test bench release clean \
        setup-armhf release-armhf test-target setup-firmware firmware upload test-firmware

help:
	@echo "make run    - install what is missing, build, start the server (http://127.0.0.1:4000)"
	@echo "make test   - the whole test suite (ExUnit, vitest, Node protocol test, Playwright, a smoke"
	@echo "              run of every benchmark, dialyzer)"
	@echo "make setup  - install Debian, npm and test-only Python dependencies (idempotent)"
	@echo "make assets - build the browser code into priv/static"
	@echo "make bench  - benchmarks (figures, not assertions)"
	@echo "make release - the deployable node in _build/prod/rel/neptunus (see rel/neptunus.service)"
	@echo "make release-armhf - the node for a Debian 12 armhf board (BeagleBone), built here:"
	@echo "                     _build/armhf/neptunus-<version>-armhf.tar.gz (see README, Deploy)"
	@echo "make test-target - the slow release tests: armhf tarball booted under qemu, install/rollback"
	@echo "make firmware - the BeagleBone SD-card image and its signed update, built here:"
	@echo "                _build/firmware/neptunus-<version>-beaglebone.img.xz and .fw (README, Flash)"
	@echo "make upload HOST=192.168.254.1 - send the update to a vehicle over the tether (A/B, rollback)"
	@echo "make test-firmware - the image booted under qemu-system-arm: updates, rollback, power loss"
	@echo "make clean  - remove build output"

setup: setup-apt setup-links setup-npm setup-venv

# Debian packages: installed with apt when root, otherwise the exact command is printed.
setup-apt:
	@missing=$$(for p in $(APT_PACKAGES); do \
	    dpkg-query -W -f='$${Status}' $$p 2>/dev/null | grep -q "install ok installed" || echo $$p; \
	  done); \
	if [ -n "$$missing" ]; then \
	  if [ "$$(id -u)" = 0 ]; then \
	    echo "Installing Debian packages:" $$missing; \
	    apt-get update -qq || echo "apt-get update failed for some lists: installing from those it has"; \
	    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $$missing >/dev/null; \
	  else \
	    echo "Missing Debian packages. Run:"; \
	    echo "  sudo apt-get update && sudo apt-get install -y" $$missing; \
	    exit 1; \
	  fi; \
	fi
	@command -v node >/dev/null && command -v npm >/dev/null || { \
	  if [ "$$(id -u)" = 0 ]; then apt-get install -y -qq nodejs npm >/dev/null; \
	  else echo "Node.js and npm are missing. Run: sudo apt-get install -y nodejs npm"; exit 1; fi; }

# yaws lives outside the Erlang lib dir (/usr/lib/yaws-*): link it into erl_libs/ so mix.exs can
# put it on the code path (a release built with that directory added to the path directly
# fails to boot: Mix derives the release's lib root from yaws' parent directory).
setup-links: setup-apt
	@yaws=$$(ls -d /usr/lib/yaws-* 2>/dev/null | head -n1); \
	test -n "$$yaws" || { echo "erlang-yaws is not installed"; exit 1; }; \
	mkdir -p erl_libs; \
	[ "$$(readlink erl_libs/$$(basename $$yaws))" = "$$yaws" ] || ln -sfn $$yaws erl_libs/$$(basename $$yaws)

setup-npm: $(ASSETS_STAMP)

$(ASSETS_STAMP): assets/package.json assets/package-lock.json
	# `npm ci`: installs exactly what the lock says and never rewrites it (`npm install` would
	# re-resolve and rewrite the lock whenever the registry's metadata differs from it).
	cd assets && npm ci --no-audit --no-fund --loglevel=error
	@touch $@

# pymavlink and MAVProxy (PyPI) for the interoperability tests (test/support/pymavlink_interop.py,
# fake_ardusub.py, the ground station tests) and mcap for test/support/mcap_read.py, in .venv/
# made with Debian's Python: nothing is installed system-wide and the server never uses them.
setup-venv: $(VENV_STAMP)

$(VENV_STAMP): | setup-apt
	/usr/bin/python3 -m venv .venv
	.venv/bin/pip install --quiet --disable-pip-version-check pymavlink==$(PYMAVLINK_VERSION) \
	  pyserial==$(PYSERIAL_VERSION) mcap==$(MCAP_VERSION)
	.venv/bin/pip install --quiet --disable-pip-version-check --no-deps MAVProxy==$(MAVPROXY_VERSION)
	@touch $@

assets: setup-npm
	cd assets && npm run --silent build

compile: setup-links
	mix compile --warnings-as-errors

# The VM flags of the release (rel/vm.args.eex): schedulers do not busy-wait, leaving the CPU
# to the serial port program, ffmpeg and the browsers' clients (bench/README.md, control latency).
VM_FLAGS := +sbwt none +sbwtdcpu none +sbwtdio none

run: setup assets compile
	ELIXIR_ERL_OPTIONS="$${ELIXIR_ERL_OPTIONS-$(VM_FLAGS)}" mix run --no-halt

# bench/smoke: every benchmark for a second or two (BENCH_SMOKE=1), so one that no longer
# starts fails here; no figure is judged (bench/README.md)
test: setup assets
	cd assets && npm run --silent typecheck && npm run --silent test
	MIX_ENV=test mix compile --warnings-as-errors
	mix test
	bench/smoke
	mix neptunus.dialyzer

bench: setup assets
	MIX_ENV=prod mix compile
	bench/fanout
	bench/protocol_fuzz
	bench/mavlink_fuzz
	bench/control_latency
	bench/gcs_latency
	bench/open_reset
	bench/recording_export
	bench/recorder_sync
	bench/sim_camera
	bench/position
	bench/video_latency
	bench/soak
	@if [ "$$(id -u)" = 0 ]; then bench/slow_link; else echo "bench/slow_link skipped: it needs root (a network namespace and a shaped link)"; fi

# Build it on the machine it runs on (the BeagleBone's Debian): the release carries that
# machine's Erlang runtime and our C programs compiled for it.
release: setup assets
	MIX_ENV=prod mix release --overwrite

# Cross-building for a Debian 12 armhf board: the cross compiler, qemu-user (the emulated boot
# test) and `file`, installed with apt when missing; the armhf architecture is added to dpkg
# only so that `apt-get download pkg:armhf` finds the board's packages (nothing :armhf is ever
# installed here: an armhf Erlang would displace the host's through multiarch conflicts).
ARMHF_HOST_PACKAGES := gcc-arm-linux-gnueabihf libc6-dev-armhf-cross binutils-arm-linux-gnueabihf \
                       qemu-user-static file

setup-armhf:
	@missing=$$(for p in $(ARMHF_HOST_PACKAGES); do \
	    dpkg-query -W -f='$${Status}' $$p 2>/dev/null | grep -q "install ok installed" || echo $$p; \
	  done); \
	armhf=$$(dpkg --print-foreign-architectures | grep -qx armhf || echo add); \
	if [ -n "$$missing$$armhf" ]; then \
	  if [ "$$(id -u)" != 0 ]; then \
	    echo "Cross-building needs, as root:"; \
	    [ -z "$$armhf" ] || echo "  sudo dpkg --add-architecture armhf"; \
	    echo "  sudo apt-get update && sudo apt-get install -y" $$missing; \
	    exit 1; \
	  fi; \
	  [ -z "$$armhf" ] || dpkg --add-architecture armhf; \
	  apt-get update -qq; \
	  [ -z "$$missing" ] || { echo "Installing Debian packages:" $$missing; \
	    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends $$missing >/dev/null; }; \
	fi

release-armhf: setup assets setup-armhf
	rel/armhf/build

test-target: release-armhf
	MIX_ENV=test mix compile --warnings-as-errors
	mix test --only target

# The SD-card image (rel/firmware/build): Debian's armhf packages through mmdebstrap, run
# under qemu-user; the image's filesystems made without mounting anything; qemu-system-arm
# and u-boot-qemu boot it in the test.
FIRMWARE_HOST_PACKAGES := mmdebstrap arch-test qemu-system-arm u-boot-qemu u-boot-tools e2fsprogs \
                          dosfstools mtools fdisk xz-utils zstd openssl openssh-client

setup-firmware: setup-armhf
	@missing=$$(for p in $(FIRMWARE_HOST_PACKAGES); do \
	    dpkg-query -W -f='$${Status}' $$p 2>/dev/null | grep -q "install ok installed" || echo $$p; \
	  done); \
	if [ -n "$$missing" ]; then \
	  if [ "$$(id -u)" != 0 ]; then \
	    echo "Building the image needs, as root:"; \
	    echo "  sudo apt-get update && sudo apt-get install -y --no-install-recommends" $$missing; \
	    exit 1; \
	  fi; \
	  echo "Installing Debian packages:" $$missing; \
	  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends $$missing >/dev/null; \
	fi

firmware: release-armhf setup-firmware
	rel/firmware/build

upload:
	rel/firmware/upload "$(HOST)" $(FW)

test-firmware: firmware
	MIX_ENV=test mix compile --warnings-as-errors
	mix test --only firmware

clean:
	rm -rf _build priv/static test/e2e/artifacts

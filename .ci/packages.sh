# What the optional steps need from outside the repository, in one place: the Debian packages
# per step and the Python venvs. Sourced by the steps (.ci/video.sh, .ci/genicam.sh, ...) and by
# .ci/prefetch.sh, which fetches them all in the background while the workspace builds. Each
# function does nothing when what it installs is already there.

# FFmpeg's libraries and tools, and clang for the bindings (feature `video`).
video_pkgs=(ffmpeg libavcodec-dev libavformat-dev libavutil-dev libswscale-dev libavfilter-dev
            libavdevice-dev libswresample-dev clang libclang-dev pkg-config)
# Aravis and its fake GigE Vision camera (feature `genicam`); libaravis-dev lacks its dependency
# on libusb-1.0-0-dev (pkg-config fails without it); iproute2 adds 127.0.0.2 to `lo`.
genicam_pkgs=(libaravis-dev libusb-1.0-0-dev aravis-tools aravis-tools-cli pkg-config iproute2)
# pdftoppm for the marker PDF rendering test.
marker_pkgs=(poppler-utils)
# The Python package's build and tests, and the ROS 2 bag check (rosbags).
python_venv_pkgs=(maturin pytest numpy rosbags)
# The Python subscriber of the camera network, and the ROS 2 over rmw_zenoh check (rosbags for
# the CDR and the type hash, xxhash for the publisher's GID).
zenoh_venv_pkgs=("eclipse-zenoh==1.10.2" rosbags xxhash)

# apt_install PKG...: installs the packages (no recommends) unless all are installed.
apt_install() {
    if dpkg -s "$@" >/dev/null 2>&1; then
        echo "already installed: $*"
    else
        DEBIAN_FRONTEND=noninteractive apt-get update -y -qq
        DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "$@" >/dev/null
    fi
}

# chromium_install: Debian's chromium with its recommends (fonts), for the console's browser test.
chromium_install() {
    if command -v chromium >/dev/null 2>&1; then
        echo "already installed: $(chromium --version 2>/dev/null || echo chromium)"
    else
        DEBIAN_FRONTEND=noninteractive apt-get update -y -qq
        DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium >/dev/null
    fi
}

# venv_install DIR PKG...: a venv in DIR with the packages; kept when DIR holds exactly these
# (listed in DIR/ci-packages), made anew otherwise.
venv_install() {
    local dir=$1
    shift
    if [ -x "$dir/bin/python" ] && [ "$(cat "$dir/ci-packages" 2>/dev/null)" = "$*" ]; then
        echo "venv ready: $dir"
        return
    fi
    rm -rf "$dir"
    python3 -m venv "$dir"
    "$dir/bin/pip" install -q --disable-pip-version-check "$@"
    echo "$*" >"$dir/ci-packages"
}

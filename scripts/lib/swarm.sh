# Sourced by the measuring scripts: `start_swarm ARGS...` runs `shoal up
# ARGS...` (release binaries) in a session of its own, its output in
# "$work/up.log", its pid in $launcher; whatever ends the script (a failed
# step too) stops that swarm and removes $work.
bin="${CARGO_TARGET_DIR:-$HOME/.cache/shoal-target}/release"
work=$(mktemp -d)
launcher=
stop_swarm() {
    if [ -n "$launcher" ] && kill -0 "$launcher" 2>/dev/null; then
        kill -INT "$launcher"
        while kill -0 "$launcher" 2>/dev/null; do sleep 0.2; done
    fi
    rm -rf "$work"
}
trap stop_swarm EXIT
start_swarm() {
    # A session of its own: an asynchronous job of a script may ignore SIGINT.
    setsid "$bin/shoal" up "$@" >"$work/up.log" 2>&1 &
    launcher=$!
}

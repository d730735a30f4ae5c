#!/usr/bin/env bash
# The Debian package (issue 19) built from this build tree, installed into a scratch root with
# the real dpkg (its maintainer scripts run with DPKG_ROOT set, outside a chroot:
# --force-script-chrootless), run from there, then removed and purged. The running system is
# never touched: its /etc/passwd, /etc/group and /etc/systemd are compared before and after.
#  - control: Depends names the runtime libraries, conffiles lists exactly the files under /etc;
#  - install: the system user in the root (postinst -> systemd-sysusers --root); a reinstall
#    keeps an edited conffile;
#  - the installed `dronetrack --help`; `sim` of an installed scenario, then `replay` of the
#    installed /etc/dronetrack/site.json (its recordings/ pointed at the scene) with --http:
#    confirmed tracks of both drones, and the page served is the installed copy;
#  - `systemd-analyze verify` on the installed units, inside the root;
#  - remove: enabled units disabled, files gone, conffiles, state and user kept; purge: the
#    conffiles go, the state stays.
# usage: deb_test.sh BUILD_DIR WORK_DIR
set -euo pipefail
build="$1"; work="$2"
fail() { echo "package test: FAIL: $*" >&2; exit 1; }
say() { echo "package test: $*"; }
[[ $(id -u) -eq 0 ]] || { echo "package test: skipped: dpkg --root needs root"; exit 77; }
for tool in cpack dpkg dpkg-deb dpkg-shlibdeps systemd-analyze systemctl curl; do
  command -v "$tool" >/dev/null || fail "$tool not found (bash scripts/install-deps.sh --tests)"
done
rm -rf "$work"; mkdir -p "$work"
started=$SECONDS

# What `--target package` runs, writing into WORK so the build folder's own package is left be.
cpack --config "$build/CPackConfig.cmake" -B "$work/out" > "$work/cpack.log" 2>&1 \
  || fail "cpack: $(tail -3 "$work/cpack.log")"
deb="$work/out/dronetrack_$(sed -n 's/^set(CPACK_PACKAGE_VERSION "\(.*\)")/\1/p' \
  "$build/CPackConfig.cmake")_$(dpkg --print-architecture).deb"
[[ -f "$deb" ]] || fail "no $(basename "$deb") in $work/out: $(ls "$work/out")"
say "built $(basename "$deb"), $(du -k "$deb" | cut -f1) KiB, in $((SECONDS - started)) s"

# Control: dependencies from dpkg-shlibdeps, maintainer scripts, conffiles.
dpkg-deb -e "$deb" "$work/control"
depends=$(dpkg-deb -f "$deb" Depends)
for library in libfftw3-double3 libsndfile1 libddsc0debian libportaudio2 libssl3 libhwy1 \
    libcpp-httplib0.11 libstdc++6 libc6; do
  grep -q "\b$library\b" <<< "$depends" || fail "Depends lacks $library: $depends"
done
for script in postinst prerm postrm; do
  [[ -x "$work/control/$script" ]] || fail "control has no executable $script"
done
etc_files=$(dpkg-deb -c "$deb" | awk '$1 !~ /^d/ {print $6}' | sed -n 's|^\./etc/|/etc/|p' | sort)
[[ "$(sort "$work/control/conffiles")" == "$etc_files" ]] \
  || fail "conffiles $(tr '\n' ' ' < "$work/control/conffiles")!= files under /etc: $(tr '\n' ' ' <<< "$etc_files")"

# Install into a scratch root. The system's files, to prove they are left alone.
host_state() { md5sum /etc/passwd /etc/group; find /etc/systemd -maxdepth 3 2>/dev/null | sort; }
host_before=$(host_state)
root="$work/root"
mkdir -p "$root/var/lib/dpkg/updates" "$root/var/lib/dpkg/info" "$root/var/log"
touch "$root/var/lib/dpkg/status"
dpkg_root() {
  dpkg --root="$root" --log="$root/var/log/dpkg.log" --force-script-chrootless --force-depends \
    "$@" > "$work/dpkg.log" 2>&1 || fail "dpkg $*: $(tail -3 "$work/dpkg.log")"
}
dpkg_root --install "$deb"
bin="$root/usr/bin/dronetrack"
for file in usr/bin/dronetrack usr/share/dronetrack/web/index.html usr/share/dronetrack/web/app.js \
    usr/share/dronetrack/scenarios/perimeter-two-drones.json usr/share/dronetrack/site-pki.sh \
    usr/share/doc/dronetrack/deployment.md lib/systemd/system/dronetrack-fusion.service \
    lib/systemd/system/dronetrack-node@.service lib/systemd/system/dronetrack-alert.service \
    etc/dronetrack/site.json etc/dronetrack/cyclonedds.xml etc/dronetrack/on-alert; do
  [[ -e "$root/$file" ]] || fail "/$file not installed"
done
[[ -x "$bin" && -x "$root/etc/dronetrack/on-alert" && -x "$root/usr/share/dronetrack/site-pki.sh" ]] \
  || fail "an installed program is not executable"
user=$(grep '^dronetrack:' "$root/etc/passwd" || true)
[[ "$user" == *:/var/lib/dronetrack:/usr/sbin/nologin ]] || fail "user in the root's passwd: '$user'"
grep -Eq '^audio:.*[:,]dronetrack(,|$)' "$root/etc/group" || fail "dronetrack is not in audio"
# A reinstall (as an upgrade runs the scripts) keeps the site's edit of a conffile.
sed -i 's/"description": "/"description": "edited here. /' "$root/etc/dronetrack/site.json"
dpkg_root --install "$deb"
grep -q '"description": "edited here. ' "$root/etc/dronetrack/site.json" \
  || fail "reinstalling replaced the edited /etc/dronetrack/site.json"

# The installed executable, with nothing of the source tree.
unset DRONETRACK_WEB_ROOT
"$bin" --help > "$work/help.txt" || fail "dronetrack --help exited $?"
grep -q "replay" "$work/help.txt" || fail "--help lists no replay"
"$bin" demo --help | grep -q "$root/usr/share/dronetrack/scenarios/perimeter-two-drones.json" \
  || fail "demo's default scenario is not the installed one"
"$bin" sim "$root/usr/share/dronetrack/scenarios/perimeter-two-drones.json" --duration-s 12 \
  --out "$work/scene" > "$work/sim.out" 2> "$work/sim.log" || fail "sim: $(tail -1 "$work/sim.log")"
ln -s "$work/scene" "$root/etc/dronetrack/recordings"  # the site's recordings/N1.wav ...
marker="<!-- installed copy $$ -->"
echo "$marker" >> "$root/usr/share/dronetrack/web/index.html"
"$bin" replay "$root/etc/dronetrack/site.json" --tracks-out "$work/tracks.jsonl" \
  --http 127.0.0.1:0 > "$work/replay.out" 2> "$work/replay.log" &
replay=$!
trap 'kill $replay 2>/dev/null || true' EXIT
for _ in $(seq 100); do
  grep -q "still serving" "$work/replay.log" && break
  kill -0 $replay 2>/dev/null || fail "replay ended: $(tail -1 "$work/replay.log")"
  sleep 0.2
done
url=$(sed -n 's/^dronetrack: serving \(.*\)$/\1/p' "$work/replay.out")
[[ -n "$url" ]] || fail "replay printed no URL"
curl -fsS "$url" > "$work/index.html" || fail "GET $url failed"
grep -qF "$marker" "$work/index.html" || fail "the page served is not the installed copy"
curl -fsS "${url%/}/api/tracks" > "$work/api-tracks.json" || fail "GET /api/tracks failed"
grep -q '"tracks":\[{' "$work/api-tracks.json" || fail "/api/tracks has no track: $(head -c 200 "$work/api-tracks.json")"
kill -TERM $replay
wait $replay && code=0 || code=$?
trap - EXIT
[[ $code -eq 143 ]] || fail "replay exited $code on SIGTERM (expected 143): $(tail -1 "$work/replay.log")"
confirmed=$(grep -o '"id":[0-9]*,[^}]*"status":"confirmed"' "$work/tracks.jsonl" \
  | grep -o '^"id":[0-9]*' | sort -u | wc -l)
[[ $confirmed -ge 2 ]] || fail "$confirmed confirmed tracks in 12 s of the perimeter scene (2 drones)"
say "installed replay: $confirmed confirmed tracks, page from the installed prefix"

# The units, verified inside the root against systemd's own targets (copied from this machine).
mkdir -p "$root/usr/lib/systemd/system"
cp -a /lib/systemd/system/*.target "$root/usr/lib/systemd/system/"
systemd-analyze verify --root="$root" dronetrack-fusion.service dronetrack-alert.service \
  dronetrack-node@N1.service > "$work/verify.log" 2>&1 || fail "systemd-analyze verify: $(cat "$work/verify.log")"
[[ ! -s "$work/verify.log" ]] || fail "systemd-analyze verify: $(cat "$work/verify.log")"
for unit in dronetrack-fusion.service dronetrack-alert.service dronetrack-node@.service; do
  systemd-analyze security --offline=true --root="$root" "/lib/systemd/system/$unit" 2>&1 \
    | grep 'Overall exposure' || true
done

# Remove: enabled units are disabled, configuration, state and the user stay.
systemctl --root="$root" --quiet enable dronetrack-fusion.service dronetrack-node@N1.service
mkdir -p "$root/var/lib/dronetrack"; echo '{}' > "$root/var/lib/dronetrack/tracks.jsonl"
dpkg_root --remove dronetrack
for file in usr/bin/dronetrack usr/share/dronetrack lib/systemd/system/dronetrack-fusion.service; do
  [[ ! -e "$root/$file" ]] || fail "/$file left after removal"
done
links=$(find "$root/etc/systemd" -name 'dronetrack*' 2>/dev/null)
[[ -z "$links" ]] || fail "enabled links left after removal: $links"
[[ -f "$root/etc/dronetrack/site.json" && -f "$root/var/lib/dronetrack/tracks.jsonl" ]] \
  || fail "removal deleted the configuration or the state"
grep -q '^dronetrack:' "$root/etc/passwd" || fail "removal deleted the user"
dpkg_root --purge dronetrack
[[ ! -e "$root/etc/dronetrack/site.json" && -f "$root/var/lib/dronetrack/tracks.jsonl" ]] \
  || fail "purge: conffiles must go, the state stay"
[[ "$(host_state)" == "$host_before" ]] || fail "the running system's users or systemd changed"
say "installed, ran, removed and purged in $((SECONDS - started)) s"

# Sourced by the measuring scripts (serve_views.sh, board_fit.sh): the configuration of a
# `digiview serve` run on a still for figures, loopback only, no autopilot link, health lines
# every 5 s. SERVE_TOP and SERVE_TABLES, where set, add top-level keys and tables.
#
# Usage: serve_config FILE STILL PORT KIND CODEC
serve_config() {
  cat >"$1" <<TOML
source = "image:$2"
health_interval_s = 5
${SERVE_TOP:-}
[encoder]
kind = "$4"
codec = "$5"
[control]
listen = "127.0.0.1:0"
[rtsp]
address = "127.0.0.1"
port = $3
[mavlink]
endpoint = "off"
${SERVE_TABLES:-}
TOML
}

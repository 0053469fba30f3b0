"""Parameters of the `bridge` node (headset server)."""
from raspv_common.params import Param

PARAMS = [
    Param("host", "127.0.0.1", "interface to listen on; anything but loopback requires a token "
          "(0.0.0.0: every interface)", dynamic=False),
    Param("port", 8765, "HTTP page + WebSocket port (0: any free port)", minimum=0, maximum=65535, dynamic=False),
    Param("tcp_port", 8766, "plain TCP port for native clients (-1: none, 0: any free port)",
          minimum=-1, maximum=65535, dynamic=False),
    Param("token", "", "secret clients must present; generated and printed when empty and host is not loopback",
          dynamic=False),
    Param("compression", "auto", "frame encoding: auto (PNG to remote clients, raw on loopback), png or raw",
          choices=("auto", "png", "raw"), dynamic=False),
    Param("deadman_timeout", 0.5, "no teleop input for this long → one zero /cmd_vel", minimum=0.1, maximum=5.0,
          dynamic=False, unit="s"),
    Param("max_linear", 1.0, "client walking speeds are clamped to this", minimum=0.0, maximum=3.0, unit="m/s"),
    Param("max_angular", 2.0, "client turning speeds are clamped to this", minimum=0.0, maximum=6.0, unit="rad/s"),
    Param("spv_node", "spv", "node whose parameters the mode keys change", dynamic=False),
    Param("modes", [], "representation modes selected by the number keys 1, 2, … (empty: every mode of "
          "raspv_spv, in its registry order)"),
    Param("max_clients", 16, "clients served at once", minimum=1, maximum=256, dynamic=False),
    Param("max_refused", 20, "refused messages after which a client is dropped", minimum=1, maximum=10000,
          dynamic=False),
    Param("tls_cert", "", "PEM certificate: serve https/wss (WebXR needs it off localhost)", dynamic=False,
          file_kind="tls_certificate", needs=("tls_key",)),
    Param("tls_key", "", "PEM private key of tls_cert", dynamic=False, file_kind="pem", needs=("tls_cert",)),
    Param("audio_cues", ["waypoint", "obstacle", "stairs"], "spatial audio cues sent to the clients (from "
          "/nav/guidance and /stairs; empty: none); each client switches them on with 'm'",
          choices=("waypoint", "obstacle", "stairs"), dynamic=False),
]

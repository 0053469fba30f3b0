"""Parameters of the `foxglove` node (Foxglove WebSocket server)."""
from raspv_common.params import Param

PARAMS = [
    Param("host", "127.0.0.1", "interface to listen on; anything but loopback requires a token "
          "(0.0.0.0: every interface)", dynamic=False),
    Param("port", 8767, "WebSocket port (0: any free port; 8765/8766 are the headset bridge's)", minimum=0,
          maximum=65535, dynamic=False),
    Param("token", "", "secret clients must give as ws://HOST:PORT/?token=…; generated and printed when empty "
          "and host is not loopback", dynamic=False),
    Param("topics", [], "topics to serve (empty: every topic of the graph whose message type is installed)"),
    Param("exclude", ["/rosout", "/parameter_events"], "topics never served"),
    Param("max_rate", 0.0, "most messages per second forwarded on each channel; faster topics are thinned "
          "(0: every message, as published)", minimum=0.0, maximum=1000.0, unit="Hz"),
    Param("parameters", True, "serve the graph's node parameters (Foxglove's parameter panel reads and sets them)",
          dynamic=False),
    Param("discovery_period", 1.0, "how often the graph's topics are looked up", minimum=0.1, maximum=30.0,
          dynamic=False, unit="s"),
    Param("sysinfo", True, "publish this machine's CPU and memory on /sysinfo (the layout plots them)",
          dynamic=False),
]

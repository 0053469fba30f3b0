"""Parameters of the `replay` node (a recorded bag as the graph's RGB-D source)."""
from raspv_common.params import Param

PARAMS = [
    Param("bag", "", "bag to play: a directory (metadata.yaml + .mcap/.db3) or a .mcap/.db3 file", dynamic=False,
          file_kind="bag"),
    Param("rate", 1.0, "playback speed factor (2.0: twice as fast)", minimum=0.01, maximum=100.0),
    Param("start_offset", 0.0, "start this far into the bag", minimum=0.0, maximum=1e6, dynamic=False, unit="s"),
    Param("loop", False, "start again from the beginning at the end of the bag"),
    Param("paused", False, "hold playback (bag time and /clock stop)"),
    Param("topics", [], "bag topics to play (empty: all)", dynamic=False),
    Param("exclude_topics", [], "bag topics not to play", dynamic=False),
    Param("remap", [], "topic remappings '/bag/topic:=/published/topic'", dynamic=False),
    Param("tf_exclude", [], "child frames whose transforms in the recording's /tf and /tf_static are not replayed, "
          "because a pose node of the graph publishes them (replay.yaml: odom, base_link for its slam node)",
          dynamic=False),
    Param("publish_clock", True, "publish the bag's time on /clock (for nodes with use_sim_time)", dynamic=False),
    Param("clock_rate", 100.0, "/clock messages per second between bag messages", minimum=0.0, maximum=1000.0,
          dynamic=False, unit="Hz"),
    Param("wait_for_subscribers", 0, "start once the replayed topics have this many subscriptions in all "
          "(at most 30 s)", minimum=0, maximum=1000, dynamic=False),
    Param("delay", 0.0, "wait this long before starting (e.g. for late subscribers)", minimum=0.0, maximum=3600.0,
          dynamic=False, unit="s"),
    Param("at_end", "hold", "at the end of the bag: 'hold' (keep running, publish nothing more) or 'exit'",
          choices=("hold", "exit"), dynamic=False),
    Param("progress", False, "print a live status line on stderr (raspv bag play sets it)", dynamic=False),
]

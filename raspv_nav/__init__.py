"""Navigation: occupancy maps, global planner, local costmap from depth, DWA (paper §III-F3)."""

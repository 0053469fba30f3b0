"""Live views of the graph for RViz and Foxglove: markers and point clouds of what perception found
(``viz`` node) and a Foxglove WebSocket server for the graph's topics (``foxglove`` node); cores
never import rclpy (docs/viz.md)."""

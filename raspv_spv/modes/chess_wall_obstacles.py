"""Chess-Floor and Wall-Obstacles together: the world-fixed checkerboard on obstacle-free
floor, walls at half level, horizontal planes and obstacles at full level."""
from __future__ import annotations

from raspv_perception import scene_labels as L
from raspv_spv.modes.chess_floor import ChessFloorMode
from raspv_spv.modes.wall_obstacles import wall_obstacle_levels


class ChessWallObstaclesMode(ChessFloorMode):
    name = "chess_wall_obstacles"
    description = "checkerboard on free floor + walls half, horizontal planes and obstacles full"

    def levels(self, inputs, sampling, num_levels):
        labels = sampling.sample(inputs.scene_labels, fill=L.NONE)
        out = wall_obstacle_levels(labels, num_levels)
        chess = super().levels(inputs, sampling, num_levels)
        floor = labels == L.FLOOR
        out[floor] = chess[floor]
        return out

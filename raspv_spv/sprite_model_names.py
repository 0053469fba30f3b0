"""Names of the sprite models (light: imported by device-file validation before any node starts;
the models themselves are in :mod:`raspv_spv.sprite_models`)."""

SPRITE_MODELS = ("gaussian", "scoreboard", "axon_map", "biphasic_axon_map", "dynaphos")
LEVELLED_MODELS = ("biphasic_axon_map", "dynaphos")     # one sprite per brightness level

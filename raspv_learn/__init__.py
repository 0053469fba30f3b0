"""Learning encoders end to end through a differentiable twin of the phosphene simulator.

The only package that imports torch (``pip install torch==2.13.0``, CPU wheel;
requirements/learn.txt). Importing the package itself imports nothing heavy; the live side —
the ``learned`` representation mode — runs the exported ONNX encoder with onnxruntime in
:mod:`raspv_spv.modes.learned` and never imports this package's torch modules. docs/learn.md.
"""

from raspv_common.extras import require

# every module here needs torch: without the `learn` extra, one line naming its install command
require("torch", "raspv_learn (learned encoders)")

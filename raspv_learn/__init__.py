"""Learning encoders end to end through a differentiable twin of the phosphene simulator.

The only package that imports torch (``pip install torch==2.13.0``, CPU wheel;
requirements/learn.txt). Importing the package itself imports nothing heavy; the live side —
the ``learned`` representation mode — runs the exported ONNX encoder with onnxruntime in
:mod:`raspv_spv.modes.learned` and never imports this package's torch modules. docs/learn.md.
"""

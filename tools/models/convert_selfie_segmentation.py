"""Convert MediaPipe's selfie-segmentation model (TFLite, Apache-2.0) to ONNX for the
``segmentation`` node's ``person`` backend.

Run once, in a throwaway virtual environment OUTSIDE the project (TensorFlow is needed at
conversion time only; nothing here is imported by RASPV):

    python3 -m venv /tmp/tfconv/venv
    /tmp/tfconv/venv/bin/pip install tensorflow-cpu==2.21.0 tf2onnx==1.17.0 onnx==1.23.2
    /tmp/tfconv/venv/bin/pip install --no-deps mediapipe==0.10.21
    /tmp/tfconv/venv/bin/python tools/models/convert_selfie_segmentation.py \
        --out raspv_perception/models/selfie_segmentation.onnx \
        --copy-tflite tests/data/models/selfie_segmentation.tflite

mediapipe 0.10.21 is the newest wheel that ships the model files; it is installed without its
dependencies and never imported (only located with ``importlib.util.find_spec``).

tf2onnx converts every layer but MediaPipe's custom ``Convolution2DTransposeBias`` (the last,
2× upsampling layer before the sigmoid). It is a transposed convolution, stride 2, kernel 2×2,
weights OHWI, plus a bias, on an NHWC tensor; it is replaced here by
Transpose(NHWC→NCHW) → ConvTranspose(weights IOHW, bias) → Transpose(NCHW→NHWC). The result
is checked against the original run by TensorFlow Lite on random inputs before it is saved.
"""
from __future__ import annotations

import argparse
import hashlib
import importlib.util
import shutil
from pathlib import Path

import numpy as np
import onnx
import tf2onnx
from onnx import helper, numpy_helper

CUSTOM_OP = "TFL_Convolution2DTransposeBias"
OPSET = 15                      # HardSwish needs >= 14


def find_tflite(name: str) -> Path:
    spec = importlib.util.find_spec("mediapipe")
    if spec is None or spec.origin is None:
        raise SystemExit("mediapipe is not installed here: pip install --no-deps mediapipe==0.10.21")
    path = Path(spec.origin).parent / "modules" / "selfie_segmentation" / name
    if not path.is_file():
        raise SystemExit(f"{path} is missing: this mediapipe wheel does not ship the model (use 0.10.21)")
    return path


def replace_transpose_conv(model: onnx.ModelProto) -> int:
    """Replace every Convolution2DTransposeBias node with standard ONNX ops; returns how many."""
    graph = model.graph
    inits = {i.name: i for i in graph.initializer}
    replaced = 0
    for index, node in reversed(list(enumerate(graph.node))):
        if node.op_type != CUSTOM_OP:
            continue
        x, w_name, b_name = node.input
        w = numpy_helper.to_array(inits[w_name])               # OHWI (out, kh, kw, in)
        b = numpy_helper.to_array(inits[b_name])
        if w.shape[1:3] != (2, 2):
            raise SystemExit(f"{node.name}: expected a 2x2 kernel, got weights {w.shape}")
        w_iohw = np.ascontiguousarray(w.transpose(3, 0, 1, 2))   # ONNX ConvTranspose: (in, out, kh, kw)
        stem = node.name or f"transpose_conv_{index}"
        graph.initializer.extend([numpy_helper.from_array(w_iohw, f"{stem}_W"),
                                  numpy_helper.from_array(b.astype(np.float32), f"{stem}_B")])
        new = [helper.make_node("Transpose", [x], [f"{stem}_nchw"], perm=[0, 3, 1, 2], name=f"{stem}_to_nchw"),
               helper.make_node("ConvTranspose", [f"{stem}_nchw", f"{stem}_W", f"{stem}_B"], [f"{stem}_out"],
                                strides=[2, 2], kernel_shape=[2, 2], name=f"{stem}_convtranspose"),
               helper.make_node("Transpose", [f"{stem}_out"], list(node.output), perm=[0, 2, 3, 1],
                                name=f"{stem}_to_nhwc")]
        del graph.node[index]
        for k, n in enumerate(new):
            graph.node.insert(index + k, n)
        replaced += 1
    used = {i for n in graph.node for i in n.input}
    unused = [i for i in graph.initializer if i.name not in used]
    for i in unused:
        graph.initializer.remove(i)
    # the custom op's domain is no longer used
    keep = [o for o in model.opset_import if o.domain in ("", "ai.onnx")]
    del model.opset_import[:]
    model.opset_import.extend(keep)
    return replaced


def check_against_tflite(tflite: Path, onnx_bytes: bytes, trials: int = 4) -> float:
    """Largest |ONNX − TFLite| over random inputs in [0, 1]."""
    import onnxruntime as ort
    import tensorflow as tf

    interp = tf.lite.Interpreter(model_path=str(tflite))
    interp.allocate_tensors()
    inp, out = interp.get_input_details()[0], interp.get_output_details()[0]
    sess = ort.InferenceSession(onnx_bytes, providers=["CPUExecutionProvider"])
    rng = np.random.default_rng(0)
    worst = 0.0
    for _ in range(trials):
        x = rng.random(inp["shape"], dtype=np.float32)
        interp.set_tensor(inp["index"], x)
        interp.invoke()
        ref = interp.get_tensor(out["index"])
        got = sess.run(None, {sess.get_inputs()[0].name: x})[0]
        worst = max(worst, float(np.abs(got - ref).max()))
    return worst


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", default="selfie_segmentation.tflite",
                    help="file in mediapipe/modules/selfie_segmentation (or the landscape variant)")
    ap.add_argument("--out", required=True, type=Path, help="ONNX file to write")
    ap.add_argument("--copy-tflite", type=Path, help="also copy the original .tflite here (for the dev test)")
    args = ap.parse_args()
    tflite = find_tflite(args.model)
    model, _ = tf2onnx.convert.from_tflite(str(tflite), opset=OPSET)
    n = replace_transpose_conv(model)
    if n != 1:
        raise SystemExit(f"expected one {CUSTOM_OP} node, replaced {n}")
    model.producer_name = "raspv tools/models/convert_selfie_segmentation.py"
    model.doc_string = (f"MediaPipe selfie segmentation ({args.model}, mediapipe 0.10.21 wheel, Apache-2.0), "
                        f"converted with tf2onnx {tf2onnx.__version__}, opset {OPSET}. Input: 1x256x256x3 RGB "
                        "float in [0, 1] (NHWC). Output: 1x256x256x1 person probability.")
    onnx.checker.check_model(model)
    data = model.SerializeToString()
    worst = check_against_tflite(tflite, data)
    if worst > 1e-4:
        raise SystemExit(f"converted model differs from the TFLite original by {worst:.2e} (> 1e-4)")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_bytes(data)
    print(f"source   {tflite}  sha256 {hashlib.sha256(tflite.read_bytes()).hexdigest()}")
    print(f"wrote    {args.out}  sha256 {hashlib.sha256(data).hexdigest()}  ({len(data)} bytes)")
    print(f"max |onnx - tflite| on random inputs: {worst:.2e}")
    if args.copy_tflite:
        args.copy_tflite.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(tflite, args.copy_tflite)
        print(f"copied   {tflite.name} -> {args.copy_tflite}")
    licence = Path(importlib.util.find_spec("mediapipe").origin).parent.parent / "mediapipe-0.10.21.dist-info" / "LICENSE"
    if licence.is_file():
        print(f"licence  {licence}")


if __name__ == "__main__":
    main()

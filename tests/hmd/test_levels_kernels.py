"""The page's WebAssembly kernels (raspv_hmd/client/levels_kernels.wasm) are built from the committed
source (levels_kernels.wat): the .wasm carries the source's sha256 in a custom section, written by
tools/client/build_kernels.mjs. (What they draw is checked in chromium: test_levels_stream_browser.)"""
import hashlib
from pathlib import Path

CLIENT = Path(__file__).resolve().parents[2] / "raspv_hmd" / "client"


def _leb128(data: bytes, at: int) -> tuple[int, int]:
    value = shift = 0
    while True:
        byte = data[at]
        at += 1
        value |= (byte & 0x7F) << shift
        shift += 7
        if byte < 0x80:
            return value, at


def custom_sections(wasm: bytes) -> dict[str, bytes]:
    assert wasm[:8] == b"\0asm\x01\0\0\0", "not a WebAssembly 1 module"
    out, at = {}, 8
    while at < len(wasm):
        section, at = wasm[at], at + 1
        size, at = _leb128(wasm, at)
        if section == 0:
            name_len, body = _leb128(wasm, at)
            out[wasm[body:body + name_len].decode()] = wasm[body + name_len:at + size]
        at += size
    return out


def test_the_kernels_are_built_from_their_source():
    wasm = (CLIENT / "levels_kernels.wasm").read_bytes()
    source = (CLIENT / "levels_kernels.wat").read_bytes()
    recorded = custom_sections(wasm).get("raspv-source-sha256", b"").decode()
    assert recorded == hashlib.sha256(source).hexdigest(), (
        "levels_kernels.wasm was not rebuilt after levels_kernels.wat changed: "
        "npm install --prefix tools/client wabt@1.0.36 && node tools/client/build_kernels.mjs")

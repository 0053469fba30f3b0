"""Turn off the shadow-map pass of PyBullet's EGL renderer, which ignores ``shadow=0`` (no ROS).

PyBullet's ``eglRenderer`` plugin draws every ``getCameraImage`` with Bullet's
GLInstancingRenderer, whose file-level flag ``useShadowMap`` (true) makes each frame render a
4096 × 4096 shadow map first, whatever the call's ``shadow`` argument says (TinyRenderer honours
it). Without a GPU (Mesa llvmpipe) that pass is most of the frame: the apartment at 465 × 366 took
66 ms of CPU per frame with it and 25 ms without, and 39 ms even at 8 × 8 pixels
(``raspv bench sim`` prints the figure of the running machine). Depth and the body-id buffer are
unchanged; colour loses the cast shadows the simulator never asked for (a coarse map over the
whole world: diagonal bands across walls) and is lit by the plain shader.

The flag is a local (not exported) symbol of the plugin's shared object, so its address is read
from the ELF symbol table (pyelftools) and the object's load address from ``/proc/self/maps``;
the byte is cleared only when everything checks out (the symbol is a 1-byte object inside a
writable mapping of that file and holds 0 or 1). Otherwise it is left alone and the reason is
returned — a stripped or rebuilt plugin renders as before, only slower.
"""
from __future__ import annotations

import ctypes
import os

FLAG_SYMBOL = "useShadowMap"


def _load_bias(path: str, first_load_vaddr: int, first_load_offset: int) -> tuple[int, list[tuple[int, int, str]]] | None:
    """(load bias of the shared object at ``path`` in this process, its mappings (start, end,
    permissions)); None when it is not mapped."""
    real = os.path.realpath(path)
    maps, bias = [], None
    page = os.sysconf("SC_PAGE_SIZE")
    with open("/proc/self/maps") as f:
        for line in f:
            parts = line.split(None, 5)
            if len(parts) < 6 or os.path.realpath(parts[5].strip()) != real:
                continue
            start, end = (int(x, 16) for x in parts[0].split("-"))
            maps.append((start, end, parts[1]))
            if bias is None and int(parts[2], 16) == first_load_offset & ~(page - 1):
                bias = start - (first_load_vaddr & ~(page - 1))
    return (bias, maps) if bias is not None else None


def disable_shadow_map(plugin_path: str) -> str | None:
    """Clear ``useShadowMap`` in the loaded EGL plugin at ``plugin_path``: None when done (or
    already off), else why it was left alone."""
    return set_shadow_map(plugin_path, False)


def set_shadow_map(plugin_path: str, on: bool) -> str | None:
    """Set ``useShadowMap`` of the loaded EGL plugin at ``plugin_path`` (``on``: PyBullet's own
    behaviour, for benchmarks side by side): None when done, else why it was left alone."""
    try:
        from elftools.elf.elffile import ELFFile
    except ImportError:
        return "pyelftools is not installed"
    try:
        with open(plugin_path, "rb") as f:
            elf = ELFFile(f)
            symtab = elf.get_section_by_name(".symtab")
            if symtab is None:
                return "the plugin has no symbol table (stripped)"
            symbols = symtab.get_symbol_by_name(FLAG_SYMBOL) or []
            loads = [s for s in elf.iter_segments() if s["p_type"] == "PT_LOAD"]
            if not loads:
                return "the plugin has no loadable segment"
            first = loads[0]
            objects = [s for s in symbols if s["st_info"]["type"] == "STT_OBJECT" and s["st_size"] == 1]
            if len(objects) != 1:
                return f"{FLAG_SYMBOL} is not a single 1-byte object in the plugin"
            value = objects[0]["st_value"]
            located = _load_bias(plugin_path, first["p_vaddr"], first["p_offset"])
    except Exception as exc:  # noqa: BLE001 - OSError, pyelftools' ELFError on a garbled file
        return f"the plugin could not be read ({exc})"
    if located is None:
        return "the plugin is not loaded in this process"
    bias, maps = located
    address = bias + value
    if not any(start <= address < end and perms.startswith("rw") for start, end, perms in maps):
        return f"{FLAG_SYMBOL} is not in a writable mapping of the plugin"
    flag = ctypes.c_uint8.from_address(address)
    if flag.value not in (0, 1):
        return f"{FLAG_SYMBOL} holds {flag.value}, not a bool: a different build"
    flag.value = 1 if on else 0
    return None

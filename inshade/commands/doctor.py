"""`inshade doctor`: the OpenGL context inshade gets on this machine, its limits and the EGL
devices, with what to check when no GPU shows."""
from __future__ import annotations

import json


def add_parser(sub) -> None:
    p = sub.add_parser("doctor", help="GL vendor/renderer/version and the limits codegen uses",
                       description="Report the OpenGL context inshade gets here: vendor, renderer, version, "
                                   "limits that matter for codegen, software or not, the backend, and the EGL "
                                   "devices with the one in use marked. When EGL sees no GPU it says what to "
                                   "check (NVIDIA driver, NVIDIA_DRIVER_CAPABILITIES=graphics, glvnd); when "
                                   "EGL cannot start at all it suggests --gl-backend osmesa.")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=cmd_doctor)


def cmd_doctor(args) -> int:
    from inshade.runtime import context

    backend, device = context.resolve()
    devices = context.egl_device_list()
    try:
        info = context.gl_info(context.shared_context())
    except context.GLContextError:
        if not args.json:   # what can be said without a context, then the error line
            _print_egl_devices(devices, backend, device)
            if backend == "egl":
                print("hint: EGL cannot create a context here; Mesa's off-screen library may still work: "
                      "apt-get install libosmesa6, then `inshade --gl-backend osmesa doctor`")
        raise
    info["egl_devices"] = [d.describe() for d in devices]
    info["gl_backend"] = backend
    info["egl_device"] = (device or 0) if backend == "egl" else None
    if args.json:
        print(json.dumps(info, indent=2, sort_keys=True))
        return 0
    width = max(len(k) for k in info)
    for k, v in info.items():
        print(f"{k:<{width}}  {v}")
    _print_egl_devices(devices, backend, device)
    if info.get("software"):
        print("note: this is a software rasteriser (CPU); timings are not GPU timings")
    return 0


def _print_egl_devices(devices, backend: str, device) -> None:
    """The EGL device list with the one in use marked, and the NVIDIA hints when none is a GPU."""
    from inshade.runtime.context import nvidia_hints

    used = (device or 0) if backend == "egl" else None
    print(f"EGL devices ({len(devices)}; --gl-device N / INSHADE_EGL_DEVICE=N picks one):")
    for d in devices:
        mark = "*" if d.index == used else " "
        print(f"  {mark} {d.index}: {d.describe()}{'  [software]' if d.software else ''}")
    if backend != "egl":
        print(f"  (not used: the {backend} backend renders)")
    if not any(not d.software for d in devices):
        print("note: EGL sees no GPU. An NVIDIA GPU needs the driver's EGL library registered with glvnd "
              "(libnvidia-gl-*, and in a container NVIDIA_DRIVER_CAPABILITIES=graphics,compute,utility); "
              "docs/gpu.md has the steps. Checked here:")
        for hint in nvidia_hints():
            print(f"  - {hint}")

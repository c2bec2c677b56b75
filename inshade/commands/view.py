"""`inshade view`: an asset in an interactive window (glfw + imgui-bundle)."""
from __future__ import annotations

import sys

from .common import UserError, image_size, resolve


def add_parser(sub) -> None:
    from inshade.codegen import OPENGL_STORAGE_MODES

    p = sub.add_parser("view", help="interactive viewer window (glfw + imgui-bundle)",
                       description="Open ASSET (a trained/ folder, scene.json or bundle) in a window, with a "
                                   "scene picker listing trained/. Needs a display: on a headless machine use "
                                   "xvfb-run. Keys: 1-5 display modes, T neural/reference, F frame, Home reset, "
                                   "F12 screenshot, Esc quit.")
    p.add_argument("asset", nargs="?", help="asset folder or shipped asset name (default: none: choose one in the scene list)")
    p.add_argument("--width", type=image_size, default=1280)
    p.add_argument("--height", type=image_size, default=800)
    p.add_argument("--storage", choices=OPENGL_STORAGE_MODES, help="override the scene's weight storage")
    p.add_argument("--trained", help="folder the scene picker lists (default: the shipped trained/)")
    p.add_argument("--frames", type=int, help="run N frames and exit (scripts, smoke tests)")
    p.add_argument("--screenshot", help="with --frames: write this screenshot (PNG + EXR + sidecar) at the end")
    p.set_defaults(func=cmd_view)


def cmd_view(args) -> int:
    import imgui_bundle  # noqa: F401  (a missing view extra is said before the display is looked for)

    from inshade.viewer.app import NoDisplayError, ViewerApp
    size = (args.width, args.height)
    settings = {"storage": args.storage} if args.storage else None
    try:
        app = ViewerApp(resolve(args.asset) if args.asset is not None else None, size=size, settings=settings, trained_root=args.trained)
    except NoDisplayError as e:
        raise UserError(str(e)) from None
    if args.frames:
        app.step(args.frames)
        if args.screenshot:
            for k, p in app.screenshot(args.screenshot).items():
                print(f"wrote {p}", file=sys.stderr)
        app.close()
        return 0
    app.run()
    return 0

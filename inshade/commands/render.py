"""The commands that draw an asset: `inshade render` (an image and its sidecar), `export-web` (a
static WebGL2 page), `export-gltf` (a .glb with the material baked) and `serve` (the page on
localhost)."""
from __future__ import annotations

import argparse
import logging
import sys
import tempfile
import threading
from pathlib import Path

from .common import STDOUT, UserError, check_output, count, image_size, resolve, scene_settings, write_error

log = logging.getLogger("inshade")


def add_parsers(sub) -> None:
    _add_render(sub)
    _add_export_web(sub)
    _add_export_three(sub)
    _add_export_gltf(sub)
    _add_serve(sub)


def _add_program_overrides(p, shown: bool = True) -> None:
    """--storage and --lut-filter: the program's weight storage and lookup array path in place of
    the scene's (listed in --help where ``shown``; export-gltf and serve take them unlisted)."""
    from inshade.codegen import FILTERS, OPENGL_STORAGE_MODES

    p.add_argument("--storage", choices=OPENGL_STORAGE_MODES,
                   help="weight storage (default: the scene's, else auto)" if shown else argparse.SUPPRESS)
    p.add_argument("--lut-filter", choices=FILTERS,
                   help="lookup array path (default: the scene's, else exact)" if shown else argparse.SUPPRESS)


def _add_render(sub) -> None:
    p = sub.add_parser("render", help="render a bundle headless to PNG/EXR + JSON sidecar",
                       description="Render an asset headless (EGL). .png: exposure applied, then the scene's tone mapper "
                                   "(--set tonemap=none|reinhard|pbr_neutral; none unless the scene says otherwise, "
                                   "e.g. pbr_neutral for glTF files; none clips values above 1), sRGB-encoded 8-bit; "
                                   ".exr: linear float32, exposure-scaled, never tone mapped; "
                                   "a JSON sidecar records the settings, bundle digest and GL renderer. At storage "
                                   "auto on a software renderer (llvmpipe), a network whose literals would take long "
                                   "to compile reads its weights from a texture where that ends the render sooner "
                                   "(the log and the sidecar's storage_choice say so).")
    p.add_argument("bundle", nargs="?", metavar="ASSET",
                   help="asset folder (scene.json, or a bundle with a 'render' field), scene.json, bundle, "
                        "or the name of a shipped asset (e.g. prt_creature); `inshade info ASSET` lists its settings")
    p.add_argument("-o", "--output", help="image path (.png or .exr; - : a PNG on standard output, no sidecar); "
                                          "with --from defaults to <shot>.from.png")
    p.add_argument("--from", dest="from_", metavar="SIDECAR",
                   help="re-render exactly what a screenshot's JSON sidecar (shot.png.json) describes")
    p.add_argument("--width", type=image_size)
    p.add_argument("--height", type=image_size)
    _add_program_overrides(p)
    p.add_argument("--set", action="append", metavar="NAME=VALUE",
                   help="a scene setting, e.g. --set sky=sunset --set env_rotation=90 (repeatable)")
    p.add_argument("--spp", type=count, metavar="N",
                   help="samples per pixel averaged by a stochastic (accumulating) program (default 1)")
    p.set_defaults(func=cmd_render)


def _add_export_web(sub) -> None:
    p = sub.add_parser("export-web", help="an asset as a static WebGL2 / WebGPU page (index.html + inshade.js + data)",
                       description="Write ASSET as a static folder that any file server shows (python -m http.server): "
                                   "index.html (the viewer: orbit / zoom / pan, the settings, split and error views "
                                   "where the asset has a reference, progressive accumulation, frame time), "
                                   "evaluate.html (the network on a test batch), inshade.js, the programs as GLSL "
                                   "ES 3.00 and the data as data.bin + manifest.json. Planned against WebGL2's "
                                   "guaranteed limits; an asset that cannot fit is refused naming the limit. "
                                   "Settings compiled into the program or feeding per-frame work are fixed in the "
                                   "page: choose them with --set. With --api webgpu or auto the same programs are "
                                   "also written as WGSL (needs glslangValidator, spirv-opt 2025.1+ and Node.js; "
                                   "docs/web.md).")
    p.add_argument("asset", metavar="ASSET", help="asset folder, scene.json, bundle, or a shipped asset's name")
    p.add_argument("-o", "--output", required=True, metavar="DIR", help="the folder to write (new or empty)")
    _add_api(p)
    p.add_argument("--width", type=image_size, help="canvas width (default: the scene's)")
    p.add_argument("--height", type=image_size, help="canvas height (default: the scene's)")
    _add_program_overrides(p)
    p.add_argument("--set", action="append", metavar="NAME=VALUE", help="a scene setting (repeatable)")
    p.add_argument("--force", action="store_true", help="replace what the folder holds")
    p.set_defaults(func=cmd_export_web)


def _add_export_three(sub) -> None:
    p = sub.add_parser("export-three", help="a network as a three.js material (WebGLRenderer, WebGPURenderer)",
                       description="Write ASSET's network as a three.js material for your own app: "
                                   "inshade-three.js (an ES module importing three: loadNetworkMaterial, "
                                   "loadNetworkMesh), inshade-three-webgpu.js (three/webgpu's node material: "
                                   "loadNetworkNodeMaterial, loadNetworkNodeMesh), network.json (its GLSL ES 3.00 "
                                   "stages, WGSL and textures) and network.bin. Planned against WebGL2's "
                                   "guaranteed limits. Draws an image (a uv -> colour network) at the mesh's uv, "
                                   "an SDF sphere traced in a box around its bound, or a radiance field marched "
                                   "in its box.")
    p.add_argument("asset", metavar="ASSET", help="asset folder, scene.json, bundle, or a shipped asset's name")
    p.add_argument("-o", "--output", required=True, metavar="DIR", help="the folder to write (new or empty)")
    p.add_argument("--force", action="store_true", help="replace what the folder holds")
    p.set_defaults(func=cmd_export_three)


def cmd_export_three(args) -> int:
    from inshade.web.three import MODULE, export_three

    m = export_three(resolve(args.asset), args.output, force=args.force)
    print(f"wrote {args.output}/{MODULE} ({m['name']}: {len(m['textures'])} textures; "
          f"import {{ loadNetworkMesh }} from \"./{Path(args.output).name}/{MODULE}\")", file=sys.stderr)
    return 0


def _add_export_gltf(sub) -> None:
    p = sub.add_parser("export-gltf", help="an asset's mesh and material as a glTF 2.0 binary (.glb)",
                       description="Write ASSET's mesh (normals, uv, tangents; a primitive per material) with its "
                                   "material as one .glb: the material its network decodes, baked into the mesh's "
                                   "uv space by the GL runtime (--material decoded), or the glTF material the asset "
                                   "was made from (--material reference); auto picks decoded where the asset's "
                                   "program can bake it.")
    p.add_argument("asset", metavar="ASSET", help="asset folder, scene.json, a .glb/.gltf, or a shipped asset's name")
    p.add_argument("-o", "--output", required=True, metavar="OUT.glb", help="the file to write")
    p.add_argument("--material", choices=("auto", "decoded", "reference"), default="auto",
                   help="which material to write (default auto)")
    p.add_argument("--size", type=image_size, default=512, help="side of the baked textures in texels (default 512)")
    p.add_argument("--compress", choices=("none", "draco", "meshopt"), default="none",
                   help="the mesh as it is (default), or compressed: draco (KHR_draco_mesh_compression, "
                        "quantized) or meshopt (EXT_meshopt_compression, lossless); both need the gltf extra")
    p.add_argument("--textures", choices=("png", "ktx2"), default="png",
                   help="texture images: png (default), or ktx2 (KHR_texture_basisu, UASTC; needs the gltf extra)")
    p.add_argument("--set", action="append", metavar="NAME=VALUE", help="a scene setting (repeatable)")
    _add_program_overrides(p, shown=False)
    p.add_argument("--force", action="store_true", help="replace OUT.glb if it exists")
    p.set_defaults(func=cmd_export_gltf)


def _add_api(p) -> None:
    p.add_argument("--api", choices=("webgl2", "webgpu", "auto"), default="webgl2",
                   help="the page's GPU API: webgl2 (GLSL ES 3.00, default), webgpu (WGSL), or auto (both: "
                        "WebGPU where the browser has it, else WebGL2)")


def _add_serve(sub) -> None:
    p = sub.add_parser("serve", help="export ASSET to a temporary page and serve it on localhost",
                       description="Export ASSET as export-web does, into a temporary folder, and serve it on "
                                   "localhost until Ctrl+C; prints the address to open.")
    p.add_argument("asset", metavar="ASSET", help="asset folder, scene.json, bundle, or a shipped asset's name")
    p.add_argument("--port", type=int, default=8000, help="port (default 8000; 0: any free port)")
    _add_api(p)
    p.add_argument("--set", action="append", metavar="NAME=VALUE", help="a scene setting (repeatable)")
    _add_program_overrides(p, shown=False)
    p.set_defaults(func=cmd_serve)


def cmd_render(args) -> int:
    if args.output == STDOUT:   # a PNG on stdout (no sidecar: there is no file to put it beside)
        with tempfile.TemporaryDirectory() as tmp:
            image, _ = _render(args, str(Path(tmp) / "stdout.png"))
            sys.stdout.buffer.write(Path(image).read_bytes())
            sys.stdout.buffer.flush()
        log.info("wrote a PNG to standard output (no sidecar)")
        return 0
    for p in _render(args, args.output):
        print(f"wrote {p}", file=sys.stderr)
    return 0


def _render(args, output) -> tuple:
    """Render as the options say into ``output`` (an image path; None with --from); the paths written."""
    from inshade.runtime.headless import (IMAGE_SUFFIXES, render_bundle, render_from_sidecar, render_scene,
                                          save_render)

    if output is not None:
        suffix = Path(output).suffix.lower()
        if suffix not in IMAGE_SUFFIXES:
            raise UserError(f"{output}: -o: unknown image type {suffix or '(none)'!r}; use .png or .exr")
        check_output(output)
        check_output(str(output) + ".json", "-o (its .json sidecar)")
    if args.from_ is not None:
        if args.bundle is not None:
            raise UserError("render: give either an ASSET or --from SIDECAR, not both")
        if args.spp is not None:
            raise UserError("render: --from re-renders the spp its sidecar records; drop --spp")
        image, info, record = render_from_sidecar(args.from_)
        out = output
        if out is None:  # shot.png.json -> shot.from.png
            image_path = Path(str(args.from_)[:-5] if str(args.from_).endswith(".json") else args.from_)
            out = image_path.with_name(image_path.stem + ".from" + (image_path.suffix or ".png"))
            check_output(out)
        paths = _save(save_render, image, info, out)
    else:
        if args.bundle is None or output is None:
            raise UserError("render: needs an ASSET and -o IMAGE (or --from SIDECAR)")
        src = resolve(args.bundle)
        settings = scene_settings(args)
        from inshade.scene.description import is_scene

        if is_scene(src):
            image, info = render_scene(src, width=args.width, height=args.height, settings=settings,
                                       spp=args.spp or 1, quick=True)
        else:
            if set(settings) - {"storage", "lut_filter"}:
                raise UserError("render: --set needs a scene (scene.json); a bare bundle has no settings")
            image, info = render_bundle(src, width=args.width, height=args.height,
                                        storage=settings.get("storage", "auto"),
                                        lut_filter=settings.get("lut_filter", "exact"), spp=args.spp or 1)
        paths = _save(save_render, image, info, output)
    return tuple(paths) if isinstance(paths, (list, tuple)) else (paths,)


def cmd_export_web(args) -> int:
    from inshade.web.export import export_web

    page = export_web(resolve(args.asset), args.output, force=args.force, settings=scene_settings(args),
                      width=args.width, height=args.height, api=args.api)
    m = page.manifest
    fixed = [s["name"] for s in m["settings"] if "fixed" in s]
    log.info("%s: %d programs, %.1f MB of data; needs %s%s", m["name"], len(page.programs), page.blob.size / 1e6,
             ", ".join(m["requires"]["extensions"]),
             "".join(f", {k} >= {v}" for k, v in m["requires"]["limits"].items()))
    if fixed:
        log.info("fixed in the page (choose with --set): %s", ", ".join(fixed))
    print(f"wrote {args.output}/index.html (serve the folder: python -m http.server -d {args.output})",
          file=sys.stderr)
    return 0


def cmd_export_gltf(args) -> int:
    from inshade.runtime.gltf_export import export_gltf

    done = export_gltf(resolve(args.asset), args.output, material=args.material, size=args.size,
                       settings=scene_settings(args), force=args.force, compress=args.compress, textures=args.textures)
    for note in done.notes:
        log.info("%s", note)
    print(f"wrote {done.path} ({done.material} material, {done.primitives} primitive"
          f"{'s' if done.primitives != 1 else ''})", file=sys.stderr)
    return 0


def cmd_serve(args) -> int:
    from inshade.web.browser import serve
    from inshade.web.export import export_web

    with tempfile.TemporaryDirectory(prefix="inshade-web-") as tmp:
        folder = Path(tmp) / "page"
        export_web(resolve(args.asset), folder, settings=scene_settings(args), api=args.api)
        try:
            with serve(folder, port=args.port) as url:
                print(f"serving {args.asset} at {url}index.html (Ctrl+C to stop)", flush=True)
                threading.Event().wait()
        except OSError as e:
            raise UserError(f"serve: --port {args.port}: {e.strerror or e}") from None
    return 0


def _save(save_render, image, info, out):
    try:
        return save_render(image, info, out)
    except OSError as e:
        raise write_error(out, e) from None

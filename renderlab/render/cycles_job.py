"""The Blender worker of the Cycles backend: ``python -m renderlab.render.cycles_job WORKDIR``.

Runs in its own process (bpy costs seconds to import and keeps global state), builds the scene once
from ``WORKDIR/scene.json`` + ``WORKDIR/scene.npz`` (written by :mod:`renderlab.render.cycles_backend`;
no pickle), then renders one frame per line read on stdin: the line names a frame JSON file in
WORKDIR; each render it lists is written as a multilayer float EXR. Protocol lines go to the
original stdout, prefixed ``RLJOB``: ``ready <blender version>``, ``done <frame file>``,
``error <message>``. Blender's own chatter goes to ``WORKDIR/worker.log``. A frame JSON with
``save_blend`` also saves the scene as a .blend file after rendering (:func:`save_blend`).

Cycles settings that would corrupt truth are all set explicitly: Standard view transform and linear
float EXR, box pixel filter (width from the job: 1 px for radiance, 0.01 px ≈ the pixel centre for the
truth AOVs), no adaptive sampling, no denoiser, fixed seed, sun of angle 0 with strength = irradiance
(W m⁻²; Cycles' sun strength is irradiance: a 0.5-albedo Lambert plane facing a 1000 W m⁻² sun
renders 0.5·1000/π), no shadow-terminator offsets, black world, no metadata stamps; ``render.shadows =
false`` makes every body invisible to shadow rays (``Object.visible_shadow``).
"""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path

import numpy as np

LAW_INDEX = {"lambert": 0, "lommel_seeliger": 1, "mcewen": 2, "hapke": 3}


def _osl_modules(bpy) -> None:
    """Make Blender's bundled ``oslquery`` importable (the cycles add-on needs it to read OSL parameters)."""
    site = Path(bpy.__file__).parents[3] / "python" / "lib" / f"python{sys.version_info[0]}.{sys.version_info[1]}" / "site-packages"
    if site.is_dir() and str(site) not in sys.path:
        sys.path.append(str(site))


def _reset_scene(bpy):
    sc = bpy.context.scene
    for ob in list(bpy.data.objects):
        bpy.data.objects.remove(ob)
    sc.render.engine = "CYCLES"
    cy = sc.cycles
    cy.device = "CPU"
    cy.shading_system = True  # OSL
    cy.use_adaptive_sampling = False
    cy.use_denoising = False
    cy.pixel_filter_type = "BOX"
    cy.max_bounces = 0  # direct sunlight only (the lab's max_depth = 2)
    cy.use_animated_seed = False
    cy.sample_clamp_direct = 0.0
    cy.sample_clamp_indirect = 0.0
    sc.view_settings.view_transform = "Standard"
    sc.view_settings.look = "None"
    sc.view_settings.exposure = 0.0
    sc.view_settings.gamma = 1.0
    sc.render.film_transparent = True
    sc.render.use_motion_blur = False
    sc.render.resolution_percentage = 100
    for name in dir(sc.render):
        if name.startswith("use_stamp"):
            try:
                setattr(sc.render, name, False)
            except (AttributeError, TypeError):
                pass
    world = bpy.data.worlds.new("rl_black")
    world.use_nodes = True
    bg = world.node_tree.nodes.get("Background")
    if bg is not None:
        bg.inputs["Strength"].default_value = 0.0
        bg.inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
    sc.world = world
    vl = sc.view_layers[0]
    vl.use_pass_combined = True
    vl.use_pass_position = True
    vl.use_pass_normal = True
    vl.use_pass_z = False  # planar depth; not needed (range comes from P) and its 1-channel part breaks
    # Blender 5.0.1 multilayer EXR writing when the pixel aspect is not 1
    vl.use_pass_object_index = True
    im = sc.render.image_settings
    im.media_type = "MULTI_LAYER_IMAGE"
    im.file_format = "OPEN_EXR_MULTILAYER"
    im.color_depth = "32"
    im.exr_codec = "ZIP"
    im.use_exr_interleave = True  # one part: the per-pass parts of 5.0.1 conflict when pixel aspect != 1
    return sc


def _material(bpy, body: dict, arrays, osl_path: str, has_attr: bool, has_map: bool):
    import cycles.osl as cycles_osl

    mat = bpy.data.materials.new(f"rl_{body['name']}")
    mat.use_nodes = True
    nt = mat.node_tree
    for n in list(nt.nodes):
        nt.nodes.remove(n)
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    scr = nt.nodes.new("ShaderNodeScript")
    scr.mode = "EXTERNAL"
    scr.filepath = osl_path
    errors = []
    ok = cycles_osl.update_script_node(scr, lambda kind, msg: errors.append(msg))
    if not ok:
        raise RuntimeError(f"OSL compile of {osl_path} failed: {'; '.join(errors)}")
    law = body["law"]
    params = {"law": LAW_INDEX[law["name"]], "albedo": float(body["albedo"])}
    for key in ("alpha0", "ls_weight", "b0", "h", "theta_bar", "xi"):
        if key in law:
            params[key] = float(law[key])
    if law.get("b") is not None:
        params.update(b=float(law["b"]), c=float(law["c"]), double_lobe=1)
    for key, value in params.items():
        scr.inputs[key].default_value = value
    nt.links.new(scr.outputs["BSDF"], out.inputs["Surface"])
    k = body["key"]
    if has_attr:
        attr = nt.nodes.new("ShaderNodeAttribute")
        attr.attribute_type = "GEOMETRY"
        attr.attribute_name = "rl_albedo"
        nt.links.new(attr.outputs["Fac"], scr.inputs["albedo_factor"])
    elif has_map:
        amap = np.asarray(arrays[f"map_{k}"], np.float32)
        h, w = amap.shape
        img = bpy.data.images.new(f"rl_map_{k}", w, h, float_buffer=True, is_data=True)
        img.colorspace_settings.is_data = True  # before the pixels: changing it regenerates (blanks) the image
        rgba = np.repeat(amap[..., None], 4, axis=2)
        rgba[..., 3] = 1.0
        # map row 0 goes to Blender's pixel row 0 (its v in [0, 1/h]); with uv passed unchanged the
        # texel centre of map (row, col) is at u = (col + 1/2)/w, v = (row + 1/2)/h, the lab's convention
        img.pixels.foreach_set(rgba.ravel())
        tex = nt.nodes.new("ShaderNodeTexImage")
        tex.image = img
        tex.interpolation = "Linear"
        tex.extension = "EXTEND"
        sep = nt.nodes.new("ShaderNodeSeparateColor")
        nt.links.new(tex.outputs["Color"], sep.inputs["Color"])
        nt.links.new(sep.outputs[0], scr.inputs["albedo_factor"])
    return mat, scr


def _add_body(bpy, sc, body: dict, arrays, osl_path: str, shadows: bool = True):
    k = body["key"]
    V = np.asarray(arrays[f"v_{k}"], np.float64)
    F = np.asarray(arrays[f"f_{k}"], np.int64)
    me = bpy.data.meshes.new(body["name"])
    me.vertices.add(len(V))
    me.vertices.foreach_set("co", V.astype(np.float32).ravel())
    me.loops.add(F.size)
    me.loops.foreach_set("vertex_index", F.astype(np.int32).ravel())
    me.polygons.add(len(F))
    me.polygons.foreach_set("loop_start", (np.arange(len(F), dtype=np.int32) * 3))
    me.update(calc_edges=True)
    has_attr = f"va_{k}" in arrays
    has_map = f"map_{k}" in arrays
    if has_attr:
        att = me.attributes.new("rl_albedo", "FLOAT", "POINT")
        att.data.foreach_set("value", np.asarray(arrays[f"va_{k}"], np.float32))
    if f"uv_{k}" in arrays:
        uv = me.uv_layers.new(name="UVMap")
        uv.data.foreach_set("uv", np.asarray(arrays[f"uv_{k}"], np.float32)[F.ravel()].ravel())
    if f"n_{k}" in arrays:  # smooth shading with exact vertex normals (the tessellated sphere)
        me.shade_smooth()
        me.normals_split_custom_set_from_vertices(np.asarray(arrays[f"n_{k}"], np.float32))
    else:
        me.shade_flat()
    ob = bpy.data.objects.new(body["name"], me)
    sc.collection.objects.link(ob)
    ob.pass_index = int(body["body_id"]) + 1
    ob.visible_shadow = bool(shadows)  # render.shadows = false: no shadow rays stop at this body
    for attr in ("shadow_terminator_offset", "shadow_terminator_geometry_offset"):
        if hasattr(ob, attr):
            setattr(ob, attr, 0.0)
    mat, scr = _material(bpy, body, arrays, osl_path, has_attr, has_map)
    me.materials.append(mat)
    return scr


def build(workdir: Path):
    """Load bpy and build the scene of ``workdir``; returns (bpy, scene, script nodes, sun object)."""
    import bpy

    _osl_modules(bpy)
    desc = json.loads((workdir / "scene.json").read_text())
    arrays = np.load(workdir / "scene.npz", allow_pickle=False)
    sc = _reset_scene(bpy)
    scripts = [_add_body(bpy, sc, body, arrays, desc["osl_path"], desc.get("shadows", True)) for body in desc["bodies"]]
    light = bpy.data.lights.new("rl_sun", "SUN")
    light.angle = 0.0
    sun = bpy.data.objects.new("rl_sun", light)
    sc.collection.objects.link(sun)
    cam_data = bpy.data.cameras.new("rl_camera")
    cam = bpy.data.objects.new("rl_camera", cam_data)
    sc.collection.objects.link(cam)
    sc.camera = cam
    return bpy, sc, scripts, sun, cam


def _matrix(M):
    from mathutils import Matrix

    return Matrix([list(map(float, row)) for row in M])


def render_frame(bpy, sc, scripts, sun, cam, job: dict, workdir: Path) -> None:
    """Set camera, sun and settings of one frame and write each requested render as an EXR."""
    c = job["camera"]
    sc.render.resolution_x, sc.render.resolution_y = int(c["width"]), int(c["height"])
    sc.render.pixel_aspect_x, sc.render.pixel_aspect_y = float(c["pixel_aspect_x"]), float(c["pixel_aspect_y"])
    cd = cam.data
    cd.type = "PERSP"
    cd.sensor_fit = "HORIZONTAL"
    cd.sensor_width = float(c["sensor_width_mm"])
    cd.lens = float(c["lens_mm"])
    cd.shift_x, cd.shift_y = float(c["shift_x"]), float(c["shift_y"])
    cd.clip_start, cd.clip_end = float(job["near_clip_m"]), float(job["far_clip_m"])
    cam.matrix_world = _matrix(job["T_render_from_blender_cam"])
    sun.matrix_world = _matrix(job["T_render_from_sun_lamp"])
    sun.data.energy = float(job["irradiance_w_m2"])
    for scr in scripts:
        scr.inputs["sun_dir"].default_value = tuple(float(v) for v in job["sun_direction_render"])
    for r in job["renders"]:
        sc.cycles.samples = int(r["samples"])
        sc.cycles.filter_width = float(r["filter_width_px"])
        sc.cycles.seed = int(r["seed"])
        sc.render.filepath = str(workdir / r["exr"])
        bpy.ops.render.render(write_still=True)


def _set_path(owner, attr: str, value: str) -> None:
    """Set a fixed-size path field, overwriting the old bytes (Blender saves the whole buffer, old tail too)."""
    setattr(owner, attr, " " * 1000)
    setattr(owner, attr, value)


def _embed_script(bpy, scr) -> None:
    """Switch an external OSL script node to an internal text block (same source, same input values)."""
    import cycles.osl as cycles_osl

    src = Path(bpy.path.abspath(scr.filepath))
    text = bpy.data.texts.get(src.name) or bpy.data.texts.new(src.name)
    text.from_string(src.read_text())
    values = {s.name: (tuple(s.default_value) if hasattr(s.default_value, "__len__") else s.default_value)
              for s in scr.inputs if hasattr(s, "default_value")}
    scr.mode = "INTERNAL"
    scr.script = text
    _set_path(scr, "filepath", "")
    errors = []
    if not cycles_osl.update_script_node(scr, lambda kind, msg: errors.append(msg)):
        raise RuntimeError(f"OSL compile of the embedded {src.name} failed: {'; '.join(errors)}")
    for name, value in values.items():
        if name in scr.inputs:
            scr.inputs[name].default_value = value


def save_blend(bpy, sc, scripts, path: str) -> None:
    """Save the scene as this frame rendered it to ``path`` (a .blend a user opens in Blender's GUI).

    Nothing in it points into the worker's temporary folder: the OSL shader source is embedded as a
    text block, generated albedo-map images are packed, the output path is relative (``//``) and
    remaining paths are remapped relative to the file. No ``.blend1`` backup is written.
    """
    for scr in scripts:
        if scr.mode == "EXTERNAL":
            _embed_script(bpy, scr)
    for img in bpy.data.images:
        if img.packed_file is None and img.source in ("GENERATED", "FILE") and img.has_data:
            img.pack()
    bpy.ops.file.pack_all()
    _set_path(sc.render, "filepath", "//" + Path(path).stem + "_")
    bpy.context.preferences.filepaths.save_version = 0
    bpy.ops.wm.save_as_mainfile(filepath=str(path), relative_remap=True, copy=True, compress=False,
                                check_existing=False)


def main(argv=None) -> int:
    workdir = Path((argv or sys.argv[1:])[0])
    proto = os.fdopen(os.dup(1), "w", buffering=1)
    log = os.open(workdir / "worker.log", os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o644)
    os.dup2(log, 1)
    os.dup2(log, 2)
    try:
        bpy, sc, scripts, sun, cam = build(workdir)
        proto.write(f"RLJOB ready {bpy.app.version_string}\n")
    except Exception as exc:  # noqa: BLE001 - reported to the parent, which raises
        proto.write(f"RLJOB error {type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}\n")
        proto.flush()
        os._exit(1)
    for line in sys.stdin:
        name = line.strip()
        if not name:
            continue
        try:
            job = json.loads((workdir / name).read_text())
            render_frame(bpy, sc, scripts, sun, cam, job, workdir)
            if job.get("save_blend"):
                save_blend(bpy, sc, scripts, job["save_blend"])
            proto.write(f"RLJOB done {name}\n")
        except Exception as exc:  # noqa: BLE001
            proto.write(f"RLJOB error {type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}\n")
    proto.flush()
    os._exit(0)  # skip bpy's interpreter-exit teardown (it raises harmless ReferenceErrors)


if __name__ == "__main__":
    sys.exit(main())

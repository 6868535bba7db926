"""Render an OBJ scene with Blender Cycles (bpy) exactly as `kdtrace render` does.

Same triangles split by material (objscene.py), one object each, built directly (Blender's OBJ
importer would make Principled BSDFs and rotate the axes). Each material is a Diffuse BSDF with
colour Kd plus, where Ke is non-zero, an Emission of colour Ke mixed with black by the Geometry
node's Backfacing output, so emission is one-sided from the counter-clockwise side as in kdtrace
(Cycles mesh emission is two-sided). Black world, box pixel filter of width 1, max_bounces =
bounces (Mitsuba's max_depth - 2), no clamping, no denoising, no adaptive sampling, light
threshold 0, Standard view transform, 2 fixed threads, 32-bit float linear EXR out. The camera is
placed by an explicit matrix from eye/target/up (Blender cameras look down their local -Z with +Y
up) and its vertical field of view. Coincident twin triangles are dropped (`objscene.load`):
Cycles' rays skip only the triangle they leave, so a twin would shadow its face.
"""
import json
import math
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import objscene  # noqa: E402

import bpy  # noqa: E402
from mathutils import Matrix, Vector  # noqa: E402


def material(name, kd, ke):
    m = bpy.data.materials.new(name)
    m.use_nodes = True
    nt = m.node_tree
    nt.nodes.clear()
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    diffuse = nt.nodes.new("ShaderNodeBsdfDiffuse")
    diffuse.inputs["Color"].default_value = (*kd, 1.0)
    diffuse.inputs["Roughness"].default_value = 0.0  # Lambertian (non-zero is Oren-Nayar)
    surface = diffuse.outputs["BSDF"]
    if max(ke) > 0:
        emit = nt.nodes.new("ShaderNodeEmission")
        emit.inputs["Color"].default_value = (*ke, 1.0)
        emit.inputs["Strength"].default_value = 1.0
        black = nt.nodes.new("ShaderNodeEmission")
        black.inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
        black.inputs["Strength"].default_value = 0.0
        geom = nt.nodes.new("ShaderNodeNewGeometry")
        mix = nt.nodes.new("ShaderNodeMixShader")
        nt.links.new(geom.outputs["Backfacing"], mix.inputs["Fac"])
        nt.links.new(emit.outputs["Emission"], mix.inputs[1])  # front (Fac 0)
        nt.links.new(black.outputs["Emission"], mix.inputs[2])  # back (Fac 1)
        add = nt.nodes.new("ShaderNodeAddShader")
        nt.links.new(diffuse.outputs["BSDF"], add.inputs[0])
        nt.links.new(mix.outputs["Shader"], add.inputs[1])
        surface = add.outputs["Shader"]
    nt.links.new(surface, out.inputs["Surface"])
    return m


def setup(args):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    c = scene.cycles
    c.device = "CPU"
    c.samples = args.spp
    c.use_adaptive_sampling = False
    c.use_denoising = False
    c.seed = args.seed
    c.max_bounces = args.bounces
    c.diffuse_bounces = args.bounces
    c.glossy_bounces = args.bounces
    c.transmission_bounces = args.bounces
    c.transparent_max_bounces = args.bounces
    c.volume_bounces = 0
    c.sample_clamp_direct = 0.0
    c.sample_clamp_indirect = 0.0
    c.light_sampling_threshold = 0.0
    c.caustics_reflective = True
    c.caustics_refractive = True
    c.blur_glossy = 0.0
    c.pixel_filter_type = "BOX"
    c.filter_width = 1.0
    c.film_exposure = 1.0
    scene.render.film_transparent = False
    scene.render.threads_mode = "FIXED"
    scene.render.threads = 2
    scene.render.resolution_x = args.width
    scene.render.resolution_y = args.height
    scene.render.resolution_percentage = 100
    scene.render.use_persistent_data = False
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0
    s = scene.render.image_settings
    s.file_format = "OPEN_EXR"
    s.color_mode = "RGB"
    s.color_depth = "32"
    s.exr_codec = "ZIP"

    world = bpy.data.worlds.new("black")
    world.use_nodes = True
    bg = world.node_tree.nodes["Background"]
    bg.inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
    bg.inputs["Strength"].default_value = 0.0
    scene.world = world

    for name, part in objscene.load(args.scene, drop_coincident=True).items():
        mesh = bpy.data.meshes.new(name)
        mesh.from_pydata(part["vertices"], [], part["triangles"])
        mesh.update()
        mesh.materials.append(material(name, part["Kd"], part["Ke"]))
        obj = bpy.data.objects.new(name, mesh)
        scene.collection.objects.link(obj)

    cam_data = bpy.data.cameras.new("camera")
    cam_data.type = "PERSP"
    cam_data.sensor_fit = "VERTICAL"
    cam_data.angle_y = math.radians(args.fov)
    cam_data.clip_start = 1e-4
    cam_data.clip_end = 1e6
    cam = bpy.data.objects.new("camera", cam_data)
    eye, target, up = Vector(args.eye), Vector(args.target), Vector(args.up)
    f = (target - eye).normalized()
    r = f.cross(up).normalized()
    u = r.cross(f)
    m = Matrix.Identity(4)
    for i in range(3):
        m[i][0], m[i][1], m[i][2], m[i][3] = r[i], u[i], -f[i], eye[i]
    cam.matrix_world = m
    scene.collection.objects.link(cam)
    scene.camera = cam
    return scene


def main():
    # bpy reads sys.argv only when run inside blender; as a module our own arguments are fine.
    args = objscene.parse_args(__doc__.splitlines()[0])
    t0 = time.perf_counter()
    scene = setup(args)
    load_s = time.perf_counter() - t0
    scene.render.filepath = os.path.abspath(args.out)
    t1 = time.perf_counter()
    bpy.ops.render.render(write_still=True)
    render_s = time.perf_counter() - t1
    line = {
        "renderer": f"cycles {bpy.app.version_string}", "scene": args.scene, "out": args.out,
        "spp": args.spp, "width": args.width, "height": args.height, "bounces": args.bounces,
        "load_s": load_s, "render_s": render_s, "threads": scene.render.threads,
    }
    print(json.dumps(line) if args.json else line)


if __name__ == "__main__":
    main()

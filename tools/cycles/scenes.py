"""Small firefly scenes for Cycles, built with bpy (`export.py builtin:NAME`).

Each is 64 x 64 by default, a few bounces, and made so that a few paths
carry most of the light: the fireflies the filter is for.

| name | what makes fireflies |
| --- | --- |
| caustic | a glass ball under a small bright light: its caustic on a diffuse floor is found only by floor -> glass -> light paths |
| highlight | a tiny, intense sphere light seen directly and in a glossy floor, next to diffuse -> glossy -> light paths |
| room | a closed room lit through a narrow gap in its ceiling by a light outside: everything inside is indirect |
| textured | a checker-and-noise textured floor under a small, bright point light, with a glossy ball |

    import scenes
    scenes.build("caustic")   # replaces the current file with the scene
"""

import math

import bpy

NAMES = ("caustic", "highlight", "room", "textured")


def _reset():
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    scene.render.resolution_x = scene.render.resolution_y = 64
    scene.render.resolution_percentage = 100
    scene.render.film_transparent = False
    c = scene.cycles
    c.device = "CPU"
    c.samples = 64
    c.max_bounces = 6
    c.diffuse_bounces = c.glossy_bounces = 4
    c.transmission_bounces = 6
    c.transparent_max_bounces = 4
    c.volume_bounces = 0
    c.caustics_reflective = c.caustics_refractive = True
    c.blur_glossy = 0.0
    c.sample_clamp_direct = c.sample_clamp_indirect = 0.0
    return scene


def _world(scene, strength, colour=(1.0, 1.0, 1.0)):
    world = bpy.data.worlds.new("world")
    scene.world = world
    bg = world.node_tree.nodes["Background"]
    bg.inputs["Color"].default_value = (*colour, 1.0)
    bg.inputs["Strength"].default_value = strength


def _camera(scene, location, target, lens=35.0):
    data = bpy.data.cameras.new("camera")
    data.lens = lens
    cam = bpy.data.objects.new("camera", data)
    scene.collection.objects.link(cam)
    cam.location = location
    direction = [t - l for t, l in zip(target, location)]
    from mathutils import Vector
    cam.rotation_euler = Vector(direction).to_track_quat("-Z", "Y").to_euler()
    scene.camera = cam
    return cam


def _material(name, kind, colour=(0.8, 0.8, 0.8), roughness=0.5, strength=0.0):
    mat = bpy.data.materials.new(name)
    nt = mat.node_tree
    for n in list(nt.nodes):
        nt.nodes.remove(n)
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    if kind == "diffuse":
        bsdf = nt.nodes.new("ShaderNodeBsdfDiffuse")
        bsdf.inputs["Color"].default_value = (*colour, 1.0)
    elif kind == "glass":
        bsdf = nt.nodes.new("ShaderNodeBsdfGlass")
        bsdf.inputs["Color"].default_value = (*colour, 1.0)
        bsdf.inputs["Roughness"].default_value = 0.0
        bsdf.inputs["IOR"].default_value = 1.5
    elif kind == "glossy":
        bsdf = nt.nodes.new("ShaderNodeBsdfAnisotropic")  # the Glossy BSDF
        bsdf.inputs["Color"].default_value = (*colour, 1.0)
        bsdf.inputs["Roughness"].default_value = roughness
    elif kind == "emission":
        bsdf = nt.nodes.new("ShaderNodeEmission")
        bsdf.inputs["Color"].default_value = (*colour, 1.0)
        bsdf.inputs["Strength"].default_value = strength
    else:
        raise ValueError(kind)
    nt.links.new(bsdf.outputs[0], out.inputs["Surface"])
    return mat


def _mesh(op, material, **kw):
    op(**kw)
    obj = bpy.context.active_object
    obj.data.materials.append(material)
    return obj


def _point_light(scene, location, power, radius, colour=(1.0, 1.0, 1.0)):
    data = bpy.data.lights.new("light", "POINT")
    data.energy = power
    data.shadow_soft_size = radius
    data.color = colour
    light = bpy.data.objects.new("light", data)
    light.location = location
    light.visible_camera = False  # a camera ray that hits a light has no AOV
    scene.collection.objects.link(light)
    return light


def caustic():
    scene = _reset()
    _world(scene, 0.02)
    _mesh(bpy.ops.mesh.primitive_plane_add, _material("floor", "diffuse", (0.7, 0.7, 0.7)), size=8)
    _mesh(bpy.ops.mesh.primitive_uv_sphere_add, _material("glass", "glass", (1.0, 1.0, 1.0)),
          radius=0.6, location=(0.0, 0.0, 0.9), segments=48, ring_count=24)
    bpy.ops.object.shade_smooth()
    _point_light(scene, (0.3, 0.2, 3.2), 400.0, 0.02)
    _camera(scene, (0.0, -4.0, 2.6), (0.0, 0.0, 0.3))


def highlight():
    scene = _reset()
    _world(scene, 0.05)
    _mesh(bpy.ops.mesh.primitive_plane_add, _material("floor", "glossy", (0.8, 0.8, 0.8), 0.08),
          size=8)
    _mesh(bpy.ops.mesh.primitive_cube_add, _material("wall", "diffuse", (0.6, 0.5, 0.4)),
          size=1.0, location=(-1.2, 0.8, 0.5))
    # A tiny, intense light, seen directly (a few pixels) and in the floor (a
    # highlight). A sphere light, not an emissive mesh: a scene with an
    # emissive mesh rendered differently each time it was built afresh.
    bulb = _point_light(scene, (0.6, 1.8, 0.6), 150.0, 0.03, (0.3, 0.5, 1.0))
    bulb.visible_camera = True
    _point_light(scene, (-2.0, -1.0, 4.0), 150.0, 0.5)
    _camera(scene, (0.0, -4.0, 1.2), (0.2, 1.0, 0.2))


def room():
    scene = _reset()
    _world(scene, 0.0)
    white = _material("walls", "diffuse", (0.75, 0.75, 0.75))
    # Five walls of a 4 x 4 x 3 room and a ceiling in two halves with a gap between.
    for loc, scale in (((0, 0, -0.05), (2, 2, 0.05)), ((0, 2.05, 1.5), (2, 0.05, 1.5)),
                       ((0, -2.05, 1.5), (2, 0.05, 1.5)), ((2.05, 0, 1.5), (0.05, 2, 1.5)),
                       ((-2.05, 0, 1.5), (0.05, 2, 1.5)),
                       ((-1.06, 0, 3.05), (0.98, 2, 0.05)), ((1.06, 0, 3.05), (0.98, 2, 0.05))):
        obj = _mesh(bpy.ops.mesh.primitive_cube_add, white, size=2.0, location=loc)
        obj.scale = scale
    _mesh(bpy.ops.mesh.primitive_cube_add, _material("box", "diffuse", (0.7, 0.3, 0.2)),
          size=0.8, location=(0.6, 0.7, 0.4))
    # The light is outside, above the 8 cm gap in the ceiling.
    _point_light(scene, (0.4, 0.0, 3.6), 3000.0, 0.05)
    _camera(scene, (-1.6, -1.8, 1.6), (0.6, 1.0, 1.0), lens=18.0)


def textured():
    scene = _reset()
    _world(scene, 0.03)
    floor = _material("floor", "diffuse")
    nt = floor.node_tree
    bsdf = nt.nodes["Diffuse BSDF"]
    checker = nt.nodes.new("ShaderNodeTexChecker")
    checker.inputs["Scale"].default_value = 8.0
    checker.inputs["Color1"].default_value = (0.8, 0.75, 0.6, 1.0)
    checker.inputs["Color2"].default_value = (0.1, 0.1, 0.12, 1.0)
    noise = nt.nodes.new("ShaderNodeTexNoise")
    noise.inputs["Scale"].default_value = 20.0
    mix = nt.nodes.new("ShaderNodeMix")
    mix.data_type = "RGBA"
    mix.blend_type = "MULTIPLY"
    mix.inputs["Factor"].default_value = 0.6
    nt.links.new(checker.outputs["Color"], mix.inputs["A"])
    nt.links.new(noise.outputs["Color"], mix.inputs["B"])
    nt.links.new(mix.outputs["Result"], bsdf.inputs["Color"])
    _mesh(bpy.ops.mesh.primitive_plane_add, floor, size=8)
    _mesh(bpy.ops.mesh.primitive_uv_sphere_add, _material("ball", "glossy", (0.9, 0.9, 0.9), 0.05),
          radius=0.5, location=(0.4, 0.6, 0.5), segments=32, ring_count=16)
    bpy.ops.object.shade_smooth()
    _point_light(scene, (-0.6, 0.2, 1.4), 250.0, 0.01)
    _camera(scene, (0.0, -3.5, 2.2), (0.0, 0.4, 0.2), lens=30.0)


def build(name):
    """Replaces the current Blender file with the named scene."""
    if name not in NAMES:
        raise KeyError(name)
    globals()[name]()
    bpy.context.view_layer.update()
    return bpy.context.scene

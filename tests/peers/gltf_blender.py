"""Imports a glb into Blender (background mode, Debian's package) and prints
the world positions of the named joints at the given times, in glTF axes
(Y up, metres), as one line: RESULT {"fps": .., "positions": {"<t>": {"<name>": [x, y, z]}}}.

usage: blender -b --factory-startup --python gltf_blender.py -- FILE.glb '[t0, ...]' '["tip_00", ...]'

Blender's importer turns the skin into an armature whose bones are the joints
(a bone's head is its joint's position) and the animation into an action
keyed at frame = time x fps.
"""
import json
import sys

import bpy
import numpy

# Debian 12 pairs Blender 3.4 with numpy 1.24, which dropped the `numpy.bool`
# alias that Blender 3.4's glTF importer still uses.
if "bool" not in numpy.__dict__:
    numpy.bool = numpy.bool_

args = sys.argv[sys.argv.index("--") + 1:]
glb, times, names = args[0], json.loads(args[1]), json.loads(args[2])

bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.ops.import_scene.gltf(filepath=glb)
scene = bpy.context.scene
fps = scene.render.fps / scene.render.fps_base
armatures = [o for o in scene.objects if o.type == "ARMATURE"]
if len(armatures) != 1:
    sys.exit(f"expected one armature, found {len(armatures)}")
arm = armatures[0]

positions = {}
for t in times:
    frame = t * fps
    whole = int(frame // 1)
    scene.frame_set(whole, subframe=frame - whole)
    row = {}
    for name in names:
        bone = arm.pose.bones.get(name)
        if bone is None:
            sys.exit(f"no bone named {name}")
        p = arm.matrix_world @ bone.head
        row[name] = [p.x, p.z, -p.y]  # Blender's Z up back to glTF's Y up
    positions[repr(t)] = row
print("RESULT " + json.dumps({"fps": fps, "positions": positions}))

#!/usr/bin/env python3
"""Writes the procedural scenes of this folder (scene.json files in SCENE_FORMAT).

    python3 scenes/generate.py

door: two rooms joined by a doorway whose door is opened a few degrees; the only light
hangs in the back room, so the front room is lit through a narrow gap - the case path
guiding exists for.
window: a closed room lit only by the environment (the Venice sunset map) through one
small window.
glossy: a box room with a rough metal sphere and a glass block under a small ceiling light.
caustic: a room whose only light hangs in a recess above the ceiling, behind a glass ball
set into the ceiling's opening like a lens: nearly all light enters refracted (a caustic
on the floor below, and the light seen from any diffuse point only through glass), and a
mirror on the left wall shows it again - the case light paths and bidirectional methods
exist for.
many_lights: a floor plan of 8 × 8 rooms joined by doorways, one small ceiling light in
each (64 lights of equal power): from any point most lights are behind walls, the case
learned light selection exists for.
"""
import json
import math
import os

HERE = os.path.dirname(os.path.abspath(__file__))


def quad(corners, material):
    return {"type": "quad", "material": material, "corners": [[round(c, 6) for c in p] for p in corners]}


def room(lo, hi, material, skip=()):
    """The six faces of an axis-aligned room, wound to face inwards."""
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    faces = {
        "floor": [(x0, y0, z0), (x1, y0, z0), (x1, y0, z1), (x0, y0, z1)][::-1],
        "ceiling": [(x0, y1, z0), (x0, y1, z1), (x1, y1, z1), (x1, y1, z0)][::-1],
        "left": [(x0, y0, z0), (x0, y0, z1), (x0, y1, z1), (x0, y1, z0)][::-1],
        "right": [(x1, y0, z0), (x1, y1, z0), (x1, y1, z1), (x1, y0, z1)][::-1],
        "back": [(x0, y0, z0), (x0, y1, z0), (x1, y1, z0), (x1, y0, z0)][::-1],
        "front": [(x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1)][::-1],
    }
    return [quad(c, material) for name, c in faces.items() if name not in skip]


def box(lo, hi, material, rotate_y=0.0, pivot=(0.0, 0.0, 0.0)):
    """A closed box wound outwards, turned by rotate_y radians about a vertical axis."""
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    c, s = math.cos(rotate_y), math.sin(rotate_y)

    def turn(p):
        x, y, z = p[0] - pivot[0], p[1], p[2] - pivot[2]
        return (pivot[0] + c * x + s * z, y, pivot[2] - s * x + c * z)

    faces = [
        [(x0, y0, z0), (x1, y0, z0), (x1, y0, z1), (x0, y0, z1)],
        [(x0, y1, z0), (x0, y1, z1), (x1, y1, z1), (x1, y1, z0)],
        [(x0, y0, z0), (x0, y0, z1), (x0, y1, z1), (x0, y1, z0)],
        [(x1, y0, z0), (x1, y1, z0), (x1, y1, z1), (x1, y0, z1)],
        [(x0, y0, z0), (x0, y1, z0), (x1, y1, z0), (x1, y0, z0)],
        [(x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1)],
    ]
    return [quad([turn(p) for p in f], material) for f in faces]


def door_scene():
    width, height = 4.0, 2.5
    wall = (0.0, -0.12)  # the dividing wall's two faces (front room at z > 0)
    opening = (0.4, 1.2, 2.1)  # doorway x from, x to, height
    shapes = []
    shapes += room((-width / 2, 0, wall[0]), (width / 2, height, 4.5), "white", skip=("back",))
    shapes += room((-width / 2, 0, -4.5), (width / 2, height, wall[1]), "white", skip=("front",))
    x_lo, x_hi, door_top = opening
    # The dividing wall around the doorway, one quad set per side.
    for z, facing_front in ((wall[0], True), (wall[1], False)):
        pieces = [
            ((-width / 2, 0), (x_lo, height)),
            ((x_hi, 0), (width / 2, height)),
            ((x_lo, door_top), (x_hi, height)),
        ]
        for (a, b), (c, d) in pieces:
            corners = [(a, b, z), (c, b, z), (c, d, z), (a, d, z)]
            shapes.append(quad(corners if facing_front else corners[::-1], "white"))
    # Jambs and header inside the doorway.
    z0, z1 = wall[1], wall[0]
    shapes.append(quad([(x_lo, 0, z0), (x_lo, 0, z1), (x_lo, door_top, z1), (x_lo, door_top, z0)][::-1], "white"))
    shapes.append(quad([(x_hi, 0, z0), (x_hi, door_top, z0), (x_hi, door_top, z1), (x_hi, 0, z1)][::-1], "white"))
    shapes.append(quad([(x_lo, door_top, z0), (x_hi, door_top, z0), (x_hi, door_top, z1), (x_lo, door_top, z1)], "white"))
    # The door: hinged at the doorway's left edge on the back-room side, opened 5 degrees.
    hinge = (x_lo, 0.0, wall[1])
    shapes += box((x_lo + 0.005, 0.0, wall[1] - 0.04), (x_hi - 0.005, door_top - 0.005, wall[1]), "door",
                  rotate_y=math.radians(5.0), pivot=hinge)
    # The only light: a small panel on the back room's ceiling, far from the door.
    y = height - 0.01
    shapes.append(quad([(-1.2, y, -3.6), (-1.2, y, -2.8), (-0.4, y, -2.8), (-0.4, y, -3.6)][::-1], "lamp"))
    return {
        "format": 1,
        "camera": {"eye": [-1.6, 1.3, 4.3], "target": [0.6, 1.0, 0.0], "up": [0, 1, 0],
                   "fov_y_deg": 55.0, "width": 320, "height": 240},
        "materials": {
            "white": {"type": "diffuse", "albedo": [0.75, 0.75, 0.72]},
            "door": {"type": "diffuse", "albedo": [0.55, 0.4, 0.3]},
            "lamp": {"type": "diffuse", "albedo": [0.8, 0.8, 0.8], "emission": [400, 360, 300]},
        },
        "shapes": shapes,
    }


def wall_with_hole(z, facing_front, x_range, y_range, hole, material):
    """A wall in the plane z = const with a rectangular hole, as four quads."""
    (x0, x1), (y0, y1) = x_range, y_range
    (hx0, hx1), (hy0, hy1) = hole
    pieces = [((x0, y0), (hx0, y1)), ((hx1, y0), (x1, y1)), ((hx0, y0), (hx1, hy0)), ((hx0, hy1), (hx1, y1))]
    shapes = []
    for (a, b), (c, d) in pieces:
        corners = [(a, b, z), (c, b, z), (c, d, z), (a, d, z)]
        shapes.append(quad(corners if facing_front else corners[::-1], material))
    return shapes


def window_scene():
    width, height, depth = 4.0, 2.6, 5.0
    shapes = room((-width / 2, 0, -depth), (width / 2, height, 0.0), "white", skip=("back",))
    hole = ((-0.45, 0.45), (1.2, 1.9))
    thickness = 0.15
    # The back wall at z = -depth with a window; its outside face and the reveal close it.
    shapes += wall_with_hole(-depth, True, (-width / 2, width / 2), (0, height), hole, "white")
    shapes += wall_with_hole(-depth - thickness, False, (-width / 2, width / 2), (0, height), hole, "white")
    (hx0, hx1), (hy0, hy1) = hole
    z0, z1 = -depth - thickness, -depth
    shapes.append(quad([(hx0, hy0, z0), (hx0, hy0, z1), (hx0, hy1, z1), (hx0, hy1, z0)][::-1], "white"))
    shapes.append(quad([(hx1, hy0, z0), (hx1, hy1, z0), (hx1, hy1, z1), (hx1, hy0, z1)][::-1], "white"))
    shapes.append(quad([(hx0, hy0, z0), (hx1, hy0, z0), (hx1, hy0, z1), (hx0, hy0, z1)], "white"))
    shapes.append(quad([(hx0, hy1, z0), (hx0, hy1, z1), (hx1, hy1, z1), (hx1, hy1, z0)], "white"))
    shapes += box((-1.2, 0.0, -3.2), (-0.4, 0.8, -2.4), "white", rotate_y=math.radians(20), pivot=(-0.8, 0, -2.8))
    return {
        "format": 1,
        "camera": {"eye": [1.5, 1.4, -0.3], "target": [-0.4, 1.0, -4.0], "up": [0, 1, 0],
                   "fov_y_deg": 60.0, "width": 320, "height": 240},
        "materials": {"white": {"type": "diffuse", "albedo": [0.7, 0.7, 0.7]}},
        "shapes": shapes,
        # A low sun in the window's direction: it reaches a patch of the floor and the box
        # through the window and is hidden from everywhere else.
        "environment": {"type": "image", "file": "../envmaps/venice_sunset_1k.hdr", "scale": 1.0,
                        "sun": {"direction": [0.25, 0.6, -1.0], "angular_radius_deg": 0.5,
                                "radiance": [2600.0, 2200.0, 1700.0]}},
    }


def icosphere(levels):
    """Vertices and faces of a unit sphere subdivided from an octahedron, wound outwards."""
    vertices = [(1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1)]
    faces = [(0, 2, 4), (2, 1, 4), (1, 3, 4), (3, 0, 4), (2, 0, 5), (1, 2, 5), (3, 1, 5), (0, 3, 5)]
    for _ in range(levels):
        cache, next_faces = {}, []

        def middle(a, b):
            key = (min(a, b), max(a, b))
            if key not in cache:
                p = [(vertices[a][i] + vertices[b][i]) / 2 for i in range(3)]
                n = math.sqrt(sum(c * c for c in p))
                vertices.append(tuple(c / n for c in p))
                cache[key] = len(vertices) - 1
            return cache[key]

        for a, b, c in faces:
            ab, bc, ca = middle(a, b), middle(b, c), middle(c, a)
            next_faces += [(a, ab, ca), (ab, b, bc), (ca, bc, c), (ab, bc, ca)]
        faces = next_faces
    return vertices, faces


def write_obj(path, vertices, faces, center, radius):
    with open(path, "w") as f:
        f.write("# written by scenes/generate.py\n")
        for v in vertices:
            f.write("v %.6f %.6f %.6f\n" % tuple(center[i] + radius * v[i] for i in range(3)))
        for a, b, c in faces:
            f.write("f %d %d %d\n" % (a + 1, b + 1, c + 1))


def glossy_scene(folder):
    shapes = room((-1.0, 0.0, -1.0), (1.0, 2.0, 1.0), "white", skip=("front",))
    vertices, faces = icosphere(4)
    os.makedirs(os.path.join(folder, "meshes"), exist_ok=True)
    write_obj(os.path.join(folder, "meshes", "sphere.obj"), vertices, faces, (-0.4, 0.45, -0.2), 0.45)
    shapes.append({"type": "mesh", "file": "meshes/sphere.obj", "material": "metal"})
    shapes += box((0.15, 0.0, -0.1), (0.75, 0.9, 0.5), "glass", rotate_y=math.radians(-25), pivot=(0.45, 0, 0.2))
    y = 1.995
    shapes.append(quad([(-0.15, y, -0.15), (0.15, y, -0.15), (0.15, y, 0.15), (-0.15, y, 0.15)], "lamp"))
    return {
        "format": 1,
        "camera": {"eye": [0, 1, 3.9], "target": [0, 0.8, 0], "up": [0, 1, 0],
                   "fov_y_deg": 39.3, "width": 256, "height": 256},
        "materials": {
            "white": {"type": "diffuse", "albedo": [0.72, 0.72, 0.7]},
            "metal": {"type": "conductor", "specular": [0.95, 0.8, 0.55], "alpha": 0.15},
            "glass": {"type": "dielectric", "ior": 1.5},
            "lamp": {"type": "diffuse", "albedo": [0.8, 0.8, 0.8], "emission": [60, 55, 45]},
        },
        "shapes": shapes,
    }


def caustic_scene(folder):
    hole, recess, top = 0.18, 0.3, 2.35
    shapes = room((-1.0, 0.0, -1.0), (1.0, 2.0, 1.0), "white", skip=("front", "ceiling"))
    # The ceiling around a square opening, facing down (as `room` winds it).
    y = 2.0

    def ceiling(x0, x1, z0, z1):
        return quad([(x0, y, z0), (x0, y, z1), (x1, y, z1), (x1, y, z0)][::-1], "white")

    shapes += [ceiling(-1.0, 1.0, -1.0, -hole), ceiling(-1.0, 1.0, hole, 1.0),
               ceiling(-1.0, -hole, -hole, hole), ceiling(hole, 1.0, -hole, hole)]
    # The recess above it, open at the bottom, with the lamp under its top.
    shapes += room((-recess, y, -recess), (recess, top, recess), "white", skip=("floor",))
    ly, h = top - 0.005, 0.12
    shapes.append(quad([(-h, ly, -h), (-h, ly, h), (h, ly, h), (h, ly, -h)][::-1], "lamp"))
    # The glass ball in the opening: wider than it, so light passes it but at the corners.
    vertices, faces = icosphere(4)
    os.makedirs(os.path.join(folder, "meshes"), exist_ok=True)
    write_obj(os.path.join(folder, "meshes", "ball.obj"), vertices, faces, (0.0, y, 0.0), 0.24)
    shapes.append({"type": "mesh", "file": "meshes/ball.obj", "material": "glass"})
    # A mirror on the left wall, facing into the room.
    x = -0.995
    shapes.append(quad([(x, 0.2, -0.7), (x, 0.2, 0.1), (x, 1.4, 0.1), (x, 1.4, -0.7)][::-1], "mirror"))
    return {
        "format": 1,
        "camera": {"eye": [0, 1, 3.9], "target": [0, 0.9, 0], "up": [0, 1, 0],
                   "fov_y_deg": 39.3, "width": 128, "height": 128},
        "materials": {
            "white": {"type": "diffuse", "albedo": [0.72, 0.72, 0.7]},
            "glass": {"type": "dielectric", "ior": 1.5},
            "mirror": {"type": "conductor", "specular": [0.9, 0.9, 0.9], "alpha": 0.0},
            "lamp": {"type": "diffuse", "albedo": [0.8, 0.8, 0.8], "emission": [120, 110, 90]},
        },
        "shapes": shapes,
    }


def many_lights_scene():
    rooms, size, height = 8, 4.0, 3.0
    door_half, door_top = 0.5, 2.2
    extent = rooms * size
    shapes = []
    # Floor facing up, ceiling facing down, over the whole plan.
    shapes.append(quad([(0, 0, 0), (0, 0, extent), (extent, 0, extent), (extent, 0, 0)], "white"))
    shapes.append(quad([(0, height, 0), (extent, height, 0), (extent, height, extent), (0, height, extent)], "white"))

    def wall(a, b, along_x, doorway):
        """A wall from a to b (a line at constant z if along_x, else constant x), seen
        from both sides as one two-sided quad per piece, with an optional doorway."""
        pieces = [(a, b, 0.0, height)]
        if doorway:
            mid = 0.5 * (a + b)
            pieces = [(a, mid - door_half, 0.0, height), (mid + door_half, b, 0.0, height),
                      (mid - door_half, mid + door_half, door_top, height)]
        return pieces

    for line in range(rooms + 1):
        c = line * size
        outer = line in (0, rooms)
        for cell in range(rooms):
            a, b = cell * size, (cell + 1) * size
            for along_x in (True, False):
                for u0, u1, y0, y1 in wall(a, b, along_x, not outer):
                    if along_x:  # the plane z = c
                        corners = [(u0, y0, c), (u1, y0, c), (u1, y1, c), (u0, y1, c)]
                    else:  # the plane x = c
                        corners = [(c, y0, u0), (c, y1, u0), (c, y1, u1), (c, y0, u1)]
                    # Both faces: two quads of opposite winding.
                    shapes.append(quad(corners, "white"))
                    shapes.append(quad(corners[::-1], "white"))
    # One small light per room, just under the ceiling, facing down.
    y = height - 0.01
    for i in range(rooms):
        for j in range(rooms):
            x, z = (i + 0.5) * size, (j + 0.5) * size
            h = 0.15
            shapes.append(quad([(x - h, y, z - h), (x + h, y, z - h), (x + h, y, z + h), (x - h, y, z + h)], "lamp"))
    return {
        "format": 1,
        "camera": {"eye": [9.3, 1.6, 9.2], "target": [15.0, 1.2, 14.0], "up": [0, 1, 0],
                   "fov_y_deg": 65.0, "width": 320, "height": 240},
        "materials": {
            "white": {"type": "diffuse", "albedo": [0.7, 0.7, 0.7]},
            "lamp": {"type": "diffuse", "albedo": [0.8, 0.8, 0.8], "emission": [300, 280, 250]},
        },
        "shapes": shapes,
    }


def write(name, scene):
    folder = os.path.join(HERE, name)
    os.makedirs(folder, exist_ok=True)
    with open(os.path.join(folder, "scene.json"), "w") as f:
        json.dump(scene, f, indent=1)
        f.write("\n")


if __name__ == "__main__":
    write("door", door_scene())
    write("window", window_scene())
    write("glossy", glossy_scene(os.path.join(HERE, "glossy")))
    write("many_lights", many_lights_scene())
    write("caustic", caustic_scene(os.path.join(HERE, "caustic")))

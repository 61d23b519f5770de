#!/usr/bin/env python3
"""Writes the geometry of the two interior scenes (white-room.obj, bedroom.obj and
their .mtl files) from boxes and quads. Run it from this folder; the outputs are
committed, so the renderer never needs Python. All geometry is made here: no third-party
model is used, so the files may be shipped and changed freely.

Units are metres, y is up. Emission is one-sided: a quad emits on the side its
counter-clockwise winding faces, so every emitter below is wound towards the room.
"""

import math


class Obj:
    def __init__(self, name):
        self.name = name
        self.v = []
        self.groups = []  # (material, [faces])

    def material(self, mat):
        self.groups.append((mat, []))

    def quad(self, a, b, c, d):
        """One quad a-b-c-d, counter-clockwise seen from the side it faces."""
        base = len(self.v) + 1
        self.v.extend([a, b, c, d])
        faces = self.groups[-1][1]
        faces.append((base, base + 1, base + 2))
        faces.append((base, base + 2, base + 3))

    def rect(self, axis, at, lo, hi, facing):
        """An axis-aligned rectangle on the plane `axis = at`, spanning lo..hi in the
        two other axes (in x, y, z order), facing +axis (facing = 1) or -axis (-1)."""
        u, w = [i for i in range(3) if i != axis]

        def p(s, t):
            q = [0.0, 0.0, 0.0]
            q[axis], q[u], q[w] = at, s, t
            return tuple(q)

        corners = [p(lo[0], lo[1]), p(hi[0], lo[1]), p(hi[0], hi[1]), p(lo[0], hi[1])]
        # (u, w, axis) is right-handed for axis 0 (y, z, x), 1 (x, z, y: left-handed) and 2.
        right_handed = axis != 1
        if (facing > 0) != right_handed:
            corners.reverse()
        self.quad(*corners)

    def box(self, lo, hi, bottom=True):
        """A closed box (outward faces); `bottom=False` leaves out the face on the floor."""
        for axis in range(3):
            u, w = [i for i in range(3) if i != axis]
            span_lo, span_hi = (lo[u], lo[w]), (hi[u], hi[w])
            if axis != 1 or bottom:
                self.rect(axis, lo[axis], span_lo, span_hi, -1)
            self.rect(axis, hi[axis], span_lo, span_hi, 1)

    def wall_with_hole(self, axis, at, lo, hi, hole_lo, hole_hi, facing):
        """A wall rectangle with one rectangular opening, as four rectangles."""
        (u0, w0), (u1, w1) = lo, hi
        (hu0, hw0), (hu1, hw1) = hole_lo, hole_hi
        self.rect(axis, at, (u0, w0), (u1, hw0), facing)
        self.rect(axis, at, (u0, hw1), (u1, w1), facing)
        self.rect(axis, at, (u0, hw0), (hu0, hw1), facing)
        self.rect(axis, at, (hu1, hw0), (u1, hw1), facing)

    def emitter_towards(self, centre, target, size):
        """A square emitter of side `size` at `centre`, facing `target`."""
        n = normalize(sub(target, centre))
        up = (0.0, 1.0, 0.0) if abs(n[1]) < 0.9 else (1.0, 0.0, 0.0)
        s = normalize(cross(up, n))
        t = cross(n, s)
        h = size / 2
        pts = [add(centre, add(scale(s, a * h), scale(t, b * h))) for a, b in ((-1, -1), (1, -1), (1, 1), (-1, 1))]
        self.quad(*pts)  # s x t = n: counter-clockwise seen from the n side

    def write(self):
        with open(self.name + ".obj", "w") as f:
            f.write("# Made by make_rooms.py (warpray); free to use and modify.\n")
            f.write(f"mtllib {self.name}.mtl\n")
            for p in self.v:
                f.write("v {:.4f} {:.4f} {:.4f}\n".format(*p))
            for mat, faces in self.groups:
                if faces:
                    f.write(f"usemtl {mat}\n")
                    for a, b, c in faces:
                        f.write(f"f {a} {b} {c}\n")


def sub(a, b):
    return tuple(x - y for x, y in zip(a, b))


def add(a, b):
    return tuple(x + y for x, y in zip(a, b))


def scale(a, k):
    return tuple(x * k for x in a)


def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def normalize(a):
    n = math.sqrt(sum(x * x for x in a))
    return tuple(x / n for x in a)


def write_mtl(name, entries):
    with open(name + ".mtl", "w") as f:
        f.write("# Made by make_rooms.py (warpray). Plain stand-ins: the scene file replaces\n")
        f.write("# most of these with glossy and layered materials by name.\n")
        for mat, kd, ke in entries:
            f.write(f"newmtl {mat}\nKd {kd[0]} {kd[1]} {kd[2]}\n")
            if ke:
                f.write(f"Ke {ke[0]} {ke[1]} {ke[2]}\n")


def table(o, x0, x1, z0, z1, height, top=0.04, leg=0.05):
    o.box((x0, height - top, z0), (x1, height, z1))
    for x in (x0, x1 - leg):
        for z in (z0, z1 - leg):
            o.box((x, 0.0, z), (x + leg, height - top, z + leg), bottom=False)


def white_room():
    """A white room, 4 x 2.7 x 6 m, lit only through one window: the sky and a small,
    bright sun outside light a patch of floor, and the rest of the room sees light
    after one or more bounces (like the 'white room' of the CIS-LBDPT paper)."""
    o = Obj("white-room")
    W, H, D = 4.0, 2.7, 6.0
    o.material("wall")
    o.rect(2, 0.0, (0.0, 0.0), (W, H), 1)  # back wall z = 0, facing +z
    o.rect(2, D, (0.0, 0.0), (W, H), -1)  # front wall behind the camera
    o.rect(0, 0.0, (0.0, 0.0), (H, D), 1)  # left wall x = 0
    # Right wall x = W with the window: y 0.8..2.2, z 1.6..3.6.
    o.wall_with_hole(0, W, (0.0, 0.0), (H, D), (0.8, 1.6), (2.2, 3.6), -1)
    o.material("ceiling")
    o.rect(1, H, (0.0, 0.0), (W, D), -1)
    o.material("floor")
    o.rect(1, 0.0, (0.0, 0.0), (W, D), 1)
    # Window reveal (the wall is 20 cm thick) and the outer face of the wall.
    o.material("wall")
    t = 0.2
    o.rect(1, 0.8, (W, 1.6), (W + t, 3.6), 1)
    o.rect(1, 2.2, (W, 1.6), (W + t, 3.6), -1)
    o.rect(2, 1.6, (W, 0.8), (W + t, 2.2), 1)
    o.rect(2, 3.6, (W, 0.8), (W + t, 2.2), -1)
    o.wall_with_hole(0, W + t, (-0.5, -0.5), (H + 0.5, D + 0.5), (0.8, 1.6), (2.2, 3.6), 1)
    # White furniture: a table with a box on it, a low cabinet, a sofa block, a shelf.
    o.material("furniture")
    table(o, 1.2, 2.6, 2.2, 3.1, 0.75)
    o.box((1.6, 0.75, 2.5), (1.95, 1.0, 2.8), bottom=False)
    o.box((0.05, 0.0, 0.6), (0.55, 0.8, 2.4), bottom=False)  # cabinet on the left wall
    o.box((0.6, 0.0, 0.05), (2.8, 0.45, 0.95), bottom=False)  # sofa seat on the back wall
    o.box((0.6, 0.45, 0.05), (2.8, 0.95, 0.3), bottom=False)  # sofa back
    o.box((0.05, 1.5, 3.0), (0.35, 1.54, 4.6))  # shelf
    # Outside: a grey ground, a sky panel facing the window and a sun.
    o.material("ground")
    o.rect(1, -0.02, (W + t, -4.0), (W + 6.0, D + 4.0), 1)
    o.material("sky")
    o.rect(0, W + 6.0, (-3.0, -4.0), (H + 6.0, D + 4.0), -1)
    o.material("sun")
    o.emitter_towards((W + 5.0, 5.6, 4.3), (W - 0.3, 1.0, 2.4), 0.6)
    o.write()
    write_mtl(
        "white-room",
        [
            ("wall", (0.8, 0.8, 0.8), None),
            ("ceiling", (0.8, 0.8, 0.8), None),
            ("floor", (0.7, 0.7, 0.7), None),
            ("furniture", (0.8, 0.8, 0.8), None),
            ("ground", (0.3, 0.3, 0.3), None),
            ("sky", (0.0, 0.0, 0.0), (2.7, 3.3, 4.5)),
            ("sun", (0.0, 0.0, 0.0), (900.0, 810.0, 660.0)),
        ],
    )


def bedroom():
    """A furnished bedroom, 4 x 2.6 x 4.5 m, with a window and a ceiling lamp; its
    materials have two or three layers (glossy paint, varnished wood, lacquer, coated
    metal), like the 'bedroom' of the CIS-LBDPT paper."""
    o = Obj("bedroom")
    W, H, D = 4.0, 2.6, 4.5
    o.material("paint")
    o.rect(0, 0.0, (0.0, 0.0), (H, D), 1)  # left wall (the bed's head)
    o.rect(0, W, (0.0, 0.0), (H, D), -1)  # right wall
    o.rect(2, D, (0.0, 0.0), (W, H), -1)  # wall behind the camera
    # Back wall z = 0 with the window: x 1.3..2.9, y 1.0..2.2.
    o.wall_with_hole(2, 0.0, (0.0, 0.0), (W, H), (1.3, 1.0), (2.9, 2.2), 1)
    o.material("ceiling")
    o.rect(1, H, (0.0, 0.0), (W, D), -1)
    o.material("floor")
    o.rect(1, 0.0, (0.0, 0.0), (W, D), 1)
    o.material("paint")
    t = 0.2
    o.rect(0, 1.3, (1.0, -t), (2.2, 0.0), 1)
    o.rect(0, 2.9, (1.0, -t), (2.2, 0.0), -1)
    o.rect(1, 1.0, (1.3, -t), (2.9, 0.0), 1)
    o.rect(1, 2.2, (1.3, -t), (2.9, 0.0), -1)
    o.wall_with_hole(2, -t, (-0.5, -0.5), (W + 0.5, H + 0.5), (1.3, 1.0), (2.9, 2.2), -1)
    # Bed: lacquered frame, headboard, mattress, blanket, two pillows.
    o.material("lacquer")
    o.box((0.05, 0.1, 1.8), (2.15, 0.35, 3.5), bottom=False)
    o.box((0.01, 0.0, 1.75), (0.1, 1.1, 3.55), bottom=False)
    o.material("linen")
    o.box((0.1, 0.35, 1.85), (2.1, 0.55, 3.45), bottom=False)
    o.box((0.2, 0.55, 1.95), (0.6, 0.68, 2.6), bottom=False)
    o.box((0.2, 0.55, 2.7), (0.6, 0.68, 3.35), bottom=False)
    o.material("blanket")
    o.box((0.8, 0.55, 1.82), (2.13, 0.6, 3.48), bottom=False)
    # Nightstand with a coated-copper lamp foot and a glowing shade top.
    o.material("paint2")
    o.box((0.1, 0.0, 3.65), (0.55, 0.5, 4.15), bottom=False)
    o.material("coated_metal")
    o.box((0.28, 0.5, 3.85), (0.37, 0.85, 3.95), bottom=False)
    # Wardrobe on the right wall, glossy paint.
    o.material("paint2")
    o.box((3.35, 0.0, 2.2), (3.98, 2.1, 4.3), bottom=False)
    # Desk under the window: coated metal top, aluminium legs.
    o.material("coated_metal")
    o.box((1.1, 0.72, 0.05), (3.1, 0.76, 0.65))
    o.material("aluminium")
    for x in (1.12, 3.05):
        for z in (0.07, 0.6):
            o.box((x, 0.0, z), (x + 0.03, 0.72, z + 0.03), bottom=False)
    # Rug.
    o.material("rug")
    o.box((1.0, 0.0, 1.3), (3.0, 0.01, 3.9), bottom=False)
    # Ceiling lamp: a small panel facing down.
    o.material("lamp")
    o.rect(1, H - 0.01, (1.8, 2.0), (2.2, 2.4), -1)
    # Outside: ground, sky and sun.
    o.material("ground")
    o.rect(1, -0.02, (-4.0, -6.0), (W + 4.0, -t), 1)
    o.material("sky")
    o.rect(2, -6.0, (-4.0, -3.0), (W + 4.0, H + 6.0), 1)
    o.material("sun")
    o.emitter_towards((1.2, 6.4, -5.8), (2.4, 0.0, 1.8), 0.6)
    o.write()
    write_mtl(
        "bedroom",
        [
            ("paint", (0.75, 0.7, 0.6), None),
            ("paint2", (0.3, 0.4, 0.5), None),
            ("ceiling", (0.8, 0.8, 0.8), None),
            ("floor", (0.35, 0.2, 0.1), None),
            ("lacquer", (0.25, 0.1, 0.05), None),
            ("linen", (0.8, 0.78, 0.74), None),
            ("blanket", (0.6, 0.12, 0.1), None),
            ("coated_metal", (0.7, 0.5, 0.3), None),
            ("aluminium", (0.9, 0.9, 0.9), None),
            ("rug", (0.5, 0.45, 0.3), None),
            ("lamp", (0.0, 0.0, 0.0), (40.0, 34.0, 24.0)),
            ("ground", (0.3, 0.3, 0.3), None),
            ("sky", (0.0, 0.0, 0.0), (1.8, 2.2, 3.0)),
            ("sun", (0.0, 0.0, 0.0), (600.0, 540.0, 440.0)),
        ],
    )


if __name__ == "__main__":
    white_room()
    bedroom()

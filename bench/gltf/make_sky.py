"""Writes bench/gltf/sky.pfm: a 1024x512 equirectangular daylight sky for the glTF pictures
(this repository's own, procedural): a blue gradient from zenith to a pale horizon, a sun 2 degrees
across at 35 degrees elevation with a soft glow, and a warm grey ground. Mitsuba's envmap mapping
(README, "Environment maps and punctual lights"): row 0 is +Y, u = atan2(x, -z) / 2pi.
Plain Python (no packages); PFM rows are written bottom row first."""
import math
import os
import struct

W, H = 1024, 512
SUN_ELEVATION, SUN_AZIMUTH = math.radians(35.0), math.radians(60.0)
SUN_RADIUS = math.radians(1.0)


def direction(u, v):
    phi, theta = 2 * math.pi * u, math.pi * v
    return (math.sin(phi) * math.sin(theta), math.cos(theta), -math.cos(phi) * math.sin(theta))


def radiance(d):
    x, y, z = d
    if y < 0:
        return (0.30, 0.27, 0.22)
    t = (1.0 - y) ** 4
    sky = [z_ * (1 - t) + h * t for z_, h in zip((0.18, 0.35, 0.85), (0.85, 0.9, 1.0))]
    ce = math.cos(SUN_ELEVATION)
    sun = (ce * math.sin(SUN_AZIMUTH), math.sin(SUN_ELEVATION), -ce * math.cos(SUN_AZIMUTH))
    angle = math.acos(max(-1.0, min(1.0, x * sun[0] + y * sun[1] + z * sun[2])))
    if angle < SUN_RADIUS:
        return (6000.0, 5600.0, 5000.0)
    glow = 2.0 * math.exp(-angle / 0.08)
    return tuple(s + glow * c for s, c in zip(sky, (1.0, 0.9, 0.7)))


def main():
    out = os.path.join(os.path.dirname(os.path.abspath(__file__)), "sky.pfm")
    rows = []
    for y in range(H):
        row = []
        for x in range(W):
            # Average 2x2 sub-texel directions so that the sun's edge is antialiased.
            acc = [0.0, 0.0, 0.0]
            for sy in (0.25, 0.75):
                for sx in (0.25, 0.75):
                    r = radiance(direction((x + sx) / W, (y + sy) / H))
                    acc = [a + c / 4 for a, c in zip(acc, r)]
            row.append(acc)
        rows.append(row)
    with open(out, "wb") as f:
        f.write(f"PF\n{W} {H}\n-1.0\n".encode())
        for row in reversed(rows):
            f.write(b"".join(struct.pack("<3f", *px) for px in row))
    print(out)


if __name__ == "__main__":
    main()

#!/usr/bin/python3
"""calibrated_urdf.py URDF CALIBRATION: the cell's URDF with the camera placed by
a hand-eye calibration (hand_eye_calibrate --out), printed to stdout.

The calibration holds stereo_left_optical_frame <- arm_base_link (p_camera =
T p_base). The URDF keeps its tree (table -> arm_base_link, table ->
stereo_camera_mount -> stereo_left_optical_frame, one publisher per frame:
robot_state_publisher); only the origin of the joint table_to_stereo_camera_mount
is replaced, so that the left optical frame lands where the calibration says:
T_table_mount = T_table_base * inv(T_camera_base) * inv(T_mount_optical).
launch/arm.launch runs it with camera_calibration:=FILE. Exits 1 with a message
naming the problem for a bad file.
"""
import math
import sys
import xml.etree.ElementTree as ET

import yaml


def rpy_matrix(r, p, y):
    """URDF's fixed-axis roll, pitch, yaw: R = Rz(y) Ry(p) Rx(r)."""
    cr, sr, cp, sp, cy, sy = math.cos(r), math.sin(r), math.cos(p), math.sin(p), math.cos(y), math.sin(y)
    return [[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr]]


def matrix_rpy(R):
    pitch = math.asin(max(-1.0, min(1.0, -R[2][0])))
    if abs(math.cos(pitch)) > 1e-9:
        return math.atan2(R[2][1], R[2][2]), pitch, math.atan2(R[1][0], R[0][0])
    return math.atan2(-R[1][2], R[1][1]), pitch, 0.0  # gimbal lock: roll absorbs yaw


def quaternion_matrix(x, y, z, w):
    n = math.sqrt(x * x + y * y + z * z + w * w)
    x, y, z, w = x / n, y / n, z / n, w / n
    return [[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]]


def compose(a, b):
    """(R, t) of a * b."""
    Ra, ta = a
    Rb, tb = b
    R = [[sum(Ra[i][k] * Rb[k][j] for k in range(3)) for j in range(3)] for i in range(3)]
    t = [sum(Ra[i][k] * tb[k] for k in range(3)) + ta[i] for i in range(3)]
    return R, t


def inverse(a):
    R, t = a
    Rt = [[R[j][i] for j in range(3)] for i in range(3)]
    return Rt, [-sum(Rt[i][k] * t[k] for k in range(3)) for i in range(3)]


def joint(root, name):
    for j in root.iter('joint'):
        if j.get('name') == name:
            origin = j.find('origin')
            if origin is None:
                origin = ET.SubElement(j, 'origin')
            return origin
    raise ValueError('the URDF has no joint %s' % name)


def origin_transform(origin):
    xyz = [float(v) for v in origin.get('xyz', '0 0 0').split()]
    rpy = [float(v) for v in origin.get('rpy', '0 0 0').split()]
    return rpy_matrix(*rpy), xyz


def read_calibration(path):
    with open(path) as f:
        c = yaml.safe_load(f)
    if not isinstance(c, dict):
        raise ValueError('not a calibration (expected hand_eye_calibrate --out)')
    if c.get('parent_frame') != 'stereo_left_optical_frame' or c.get('child_frame') != 'arm_base_link':
        raise ValueError('parent_frame / child_frame are %s / %s, expected stereo_left_optical_frame / arm_base_link'
                         % (c.get('parent_frame'), c.get('child_frame')))
    try:
        t = [float(c['translation'][k]) for k in 'xyz']
        q = [float(c['rotation'][k]) for k in 'xyzw']
    except (KeyError, TypeError, ValueError) as e:
        raise ValueError('translation {x y z} and rotation {x y z w} are required (%s)' % e)
    if abs(math.sqrt(sum(v * v for v in q)) - 1.0) > 1e-3:
        raise ValueError('the rotation quaternion is not a unit quaternion')
    return quaternion_matrix(*q), t


def main(argv):
    if len(argv) != 3:
        sys.stderr.write(__doc__)
        return 2
    try:
        camera_from_base = read_calibration(argv[2])
    except (OSError, ValueError, yaml.YAMLError) as e:
        sys.stderr.write('calibrated_urdf: %s: %s\n' % (argv[2], e))
        return 1
    try:
        root = ET.parse(argv[1]).getroot()
        table_from_base = origin_transform(joint(root, 'table_to_arm_base'))
        mount_from_optical = origin_transform(joint(root, 'stereo_mount_to_left_optical'))
        mount = joint(root, 'table_to_stereo_camera_mount')
    except (OSError, ET.ParseError, ValueError) as e:
        sys.stderr.write('calibrated_urdf: %s: %s\n' % (argv[1], e))
        return 1
    R, t = compose(compose(table_from_base, inverse(camera_from_base)), inverse(mount_from_optical))
    mount.set('xyz', ' '.join('%.6f' % v for v in t))
    mount.set('rpy', ' '.join('%.9f' % v for v in matrix_rpy(R)))
    sys.stdout.write(ET.tostring(root, encoding='unicode'))
    sys.stdout.write('\n')
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv))

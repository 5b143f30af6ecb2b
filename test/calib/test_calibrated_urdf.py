#!/usr/bin/python3
"""scripts/calibrated_urdf.py: the URDF's camera mount placed by a hand-eye
calibration. A calibration equal to the URDF's own camera pose leaves the mount
where it was; one shifted by 1 cm along the arm base's x moves the left optical
frame by exactly that; bad calibrations exit 1 naming the file and the problem."""
import math
import os
import subprocess
import sys
import tempfile
import unittest
import xml.etree.ElementTree as ET

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
sys.path.insert(0, os.path.join(ROOT, 'scripts'))
import calibrated_urdf as cu  # noqa: E402

URDF = os.path.join(ROOT, 'urdf', 'massage_arm.urdf')
SCRIPT = os.path.join(ROOT, 'scripts', 'calibrated_urdf.py')


def urdf_camera_from_base(root):
    """stereo_left_optical_frame <- arm_base_link from the URDF's joints."""
    table_base = cu.origin_transform(cu.joint(root, 'table_to_arm_base'))
    table_mount = cu.origin_transform(cu.joint(root, 'table_to_stereo_camera_mount'))
    mount_optical = cu.origin_transform(cu.joint(root, 'stereo_mount_to_left_optical'))
    return cu.compose(cu.inverse(cu.compose(table_mount, mount_optical)), table_base)


def matrix_quaternion(R):
    w = math.sqrt(max(0.0, 1 + R[0][0] + R[1][1] + R[2][2])) / 2
    x = math.copysign(math.sqrt(max(0.0, 1 + R[0][0] - R[1][1] - R[2][2])) / 2, R[2][1] - R[1][2])
    y = math.copysign(math.sqrt(max(0.0, 1 - R[0][0] + R[1][1] - R[2][2])) / 2, R[0][2] - R[2][0])
    z = math.copysign(math.sqrt(max(0.0, 1 - R[0][0] - R[1][1] + R[2][2])) / 2, R[1][0] - R[0][1])
    return x, y, z, w


def write_calibration(path, transform, parent='stereo_left_optical_frame'):
    R, t = transform
    x, y, z, w = matrix_quaternion(R)
    with open(path, 'w') as f:
        f.write('parent_frame: %s\nchild_frame: arm_base_link\n' % parent)
        f.write('translation: {x: %.9f, y: %.9f, z: %.9f}\n' % tuple(t))
        f.write('rotation: {x: %.12f, y: %.12f, z: %.12f, w: %.12f}\n' % (x, y, z, w))


def run(calibration):
    return subprocess.run(['/usr/bin/python3', SCRIPT, URDF, calibration], capture_output=True, text=True)


class CalibratedUrdf(unittest.TestCase):
    def setUp(self):
        self.dir = tempfile.mkdtemp()
        self.nominal = urdf_camera_from_base(ET.parse(URDF).getroot())

    def optical_in_table(self, urdf_text):
        root = ET.fromstring(urdf_text)
        table_mount = cu.origin_transform(cu.joint(root, 'table_to_stereo_camera_mount'))
        return cu.compose(table_mount, cu.origin_transform(cu.joint(root, 'stereo_mount_to_left_optical')))

    def test_the_urdfs_own_pose_leaves_the_mount(self):
        path = os.path.join(self.dir, 'nominal.yaml')
        write_calibration(path, self.nominal)
        r = run(path)
        self.assertEqual(r.returncode, 0, r.stderr)
        mount = cu.joint(ET.fromstring(r.stdout), 'table_to_stereo_camera_mount')
        for got, want in zip(mount.get('xyz').split(), ['-0.27', '0', '0.95']):
            self.assertAlmostEqual(float(got), float(want), places=6)
        for got in mount.get('rpy').split():
            self.assertAlmostEqual(float(got), 0.0, places=6)

    def test_a_shifted_calibration_moves_the_optical_frame_by_the_shift(self):
        # The arm base seen 1 cm further along its own x: the camera sits 1 cm further along -x of the base.
        R, t = self.nominal
        shifted = (R, [t[i] + R[i][0] * 0.01 for i in range(3)])
        path = os.path.join(self.dir, 'shifted.yaml')
        write_calibration(path, shifted)
        before = self.optical_in_table(open(URDF).read())
        r = run(path)
        self.assertEqual(r.returncode, 0, r.stderr)
        after = self.optical_in_table(r.stdout)
        table_base_R = cu.origin_transform(cu.joint(ET.parse(URDF).getroot(), 'table_to_arm_base'))[0]
        expected = [before[1][i] - 0.01 * table_base_R[i][0] for i in range(3)]
        for got, want in zip(after[1], expected):
            self.assertAlmostEqual(got, want, places=6)
        for i in range(3):
            for j in range(3):
                self.assertAlmostEqual(after[0][i][j], before[0][i][j], places=6)

    def test_bad_calibrations_are_named(self):
        wrong = os.path.join(self.dir, 'wrong_frames.yaml')
        write_calibration(wrong, self.nominal, parent='camera')
        r = run(wrong)
        self.assertEqual(r.returncode, 1)
        self.assertIn('wrong_frames.yaml', r.stderr)
        self.assertIn('expected stereo_left_optical_frame / arm_base_link', r.stderr)
        r = run(os.path.join(self.dir, 'missing.yaml'))
        self.assertEqual(r.returncode, 1)
        self.assertIn('missing.yaml', r.stderr)
        partial = os.path.join(self.dir, 'partial.yaml')
        with open(partial, 'w') as f:
            f.write('parent_frame: stereo_left_optical_frame\nchild_frame: arm_base_link\n')
        r = run(partial)
        self.assertEqual(r.returncode, 1)
        self.assertIn('translation {x y z} and rotation {x y z w} are required', r.stderr)


if __name__ == '__main__':
    unittest.main()

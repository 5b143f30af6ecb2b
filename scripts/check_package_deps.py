#!/usr/bin/python3
"""Checks that scripts/debian_packages.txt installs every package.xml dependency.

Usage: check_package_deps.py PACKAGE_XML DEBIAN_PACKAGES_TXT

Every <*depend> key of package.xml must appear as a key on a line of the
Debian package list. When the named Debian package is installed and ships
/usr/share/<key>/package.xml (a ROS package), the check also asks dpkg that
the file comes from a Debian package on the list. Exits 1 on any problem.
"""
import os
import subprocess
import sys
import xml.etree.ElementTree as ET

DEPEND_TAGS = ("depend", "build_depend", "build_export_depend", "exec_depend",
               "test_depend", "buildtool_depend", "doc_depend", "run_depend")


def package_keys(path):
    root = ET.parse(path).getroot()
    keys = {}
    for tag in DEPEND_TAGS:
        for element in root.findall(tag):
            keys.setdefault(element.text.strip(), tag)
    return keys


def debian_list(path):
    provided = {}
    packages = []
    with open(path) as f:
        for number, line in enumerate(f, 1):
            line = line.split("#", 1)[0].split()
            if not line:
                continue
            packages.append(line[0])
            for key in line[1:]:
                if key in provided:
                    raise SystemExit(f"{path}:{number}: key '{key}' listed twice")
                provided[key] = line[0]
    return packages, provided


def owner_of(path):
    try:
        out = subprocess.run(["dpkg", "-S", path], capture_output=True, text=True, check=False)
    except FileNotFoundError:
        return None
    if out.returncode != 0:
        return None
    return out.stdout.split(":", 1)[0].strip()


def main(argv):
    if len(argv) != 3:
        print(__doc__)
        return 2
    keys = package_keys(argv[1])
    packages, provided = debian_list(argv[2])
    problems = []
    for key, tag in sorted(keys.items()):
        if key not in provided:
            problems.append(f"package.xml <{tag}>{key}</{tag}> has no Debian package in {argv[2]}")
            continue
        manifest = f"/usr/share/{key}/package.xml"
        if os.path.exists(manifest):
            owner = owner_of(manifest)
            if owner is not None and owner not in packages:
                problems.append(f"'{key}': {manifest} comes from Debian package '{owner}', "
                                f"which {argv[2]} does not install")
    for problem in problems:
        print("FAIL:", problem)
    print(f"{len(keys)} package.xml dependencies, {len(packages)} Debian packages, "
          f"{len(problems)} problems")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))

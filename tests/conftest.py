"""Loaded before every test module: the project's CPU-kernel pins (kitti.cpu) must reach the
environment before a test module imports numpy or torch itself."""

import kitti  # noqa: F401

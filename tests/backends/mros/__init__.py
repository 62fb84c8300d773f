"""Helpers of the mROS backend tests: test applications, builds with the host and target compilers, and the
wire-format harness (see tests/backends/mros/mros_api/ for the stand-in mROS headers)."""

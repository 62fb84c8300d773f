"""What C and C++ backends share (mros today): `names` (C types of the ROS primitives, C++ keywords, the
macros of the C library and the compiler, safe comments, name mangling) and `ros1wire` (the sizes of ROS 1's
TCPROS connection headers and the message definitions they carry). A second C/C++ backend imports these
instead of copying mros's; what is mROS's own (its RTOS's macros, its buffers) stays in `mros/`.
"""

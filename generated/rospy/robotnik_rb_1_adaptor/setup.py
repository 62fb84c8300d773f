"""Install robotnik_rb_1_adaptor: through catkin (catkin_python_setup in CMakeLists.txt) or plain setuptools."""

from setuptools import setup

try:
    from catkin_pkg.python_setup import generate_distutils_setup
except ImportError:  # outside a catkin workspace: plain setuptools
    setup(
        name="robotnik_rb_1_adaptor",
        version="0.0.0",
        packages=["robotnik_rb_1_adaptor"],
        package_dir={"": "src"},
        package_data={"robotnik_rb_1_adaptor": ["py.typed"]},
    )
else:
    setup(
        **generate_distutils_setup(
            packages=["robotnik_rb_1_adaptor"],
            package_dir={"": "src"},
            package_data={"robotnik_rb_1_adaptor": ["py.typed"]},
        )
    )

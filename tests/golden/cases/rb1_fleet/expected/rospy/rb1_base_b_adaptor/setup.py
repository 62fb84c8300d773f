"""Install rb1_base_b_adaptor: through catkin (catkin_python_setup in CMakeLists.txt) or plain setuptools."""

from setuptools import setup

try:
    from catkin_pkg.python_setup import generate_distutils_setup
except ImportError:  # outside a catkin workspace: plain setuptools
    setup(
        name="rb1_base_b_adaptor",
        version="1.0.0",
        packages=["rb1_base_b_adaptor"],
        package_dir={"": "src"},
        package_data={"rb1_base_b_adaptor": ["py.typed"]},
    )
else:
    setup(
        **generate_distutils_setup(
            packages=["rb1_base_b_adaptor"],
            package_dir={"": "src"},
            package_data={"rb1_base_b_adaptor": ["py.typed"]},
        )
    )

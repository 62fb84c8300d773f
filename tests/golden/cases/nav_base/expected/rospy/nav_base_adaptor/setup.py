"""Install nav_base_adaptor: through catkin (catkin_python_setup in CMakeLists.txt) or plain setuptools."""

from setuptools import setup

try:
    from catkin_pkg.python_setup import generate_distutils_setup
except ImportError:  # outside a catkin workspace: plain setuptools
    setup(
        name="nav_base_adaptor",
        version="0.0.0",
        packages=["nav_base_adaptor"],
        package_dir={"": "src"},
        package_data={"nav_base_adaptor": ["py.typed"]},
    )
else:
    setup(
        **generate_distutils_setup(
            packages=["nav_base_adaptor"],
            package_dir={"": "src"},
            package_data={"nav_base_adaptor": ["py.typed"]},
        )
    )

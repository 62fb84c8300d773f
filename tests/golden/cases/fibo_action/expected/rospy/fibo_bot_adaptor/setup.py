"""Install fibo_bot_adaptor: through catkin (catkin_python_setup in CMakeLists.txt) or plain setuptools."""

from setuptools import setup

try:
    from catkin_pkg.python_setup import generate_distutils_setup
except ImportError:  # outside a catkin workspace: plain setuptools
    setup(
        name="fibo_bot_adaptor",
        version="0.0.0",
        packages=["fibo_bot_adaptor"],
        package_dir={"": "src"},
        package_data={"fibo_bot_adaptor": ["py.typed"]},
    )
else:
    setup(
        **generate_distutils_setup(
            packages=["fibo_bot_adaptor"],
            package_dir={"": "src"},
            package_data={"fibo_bot_adaptor": ["py.typed"]},
        )
    )

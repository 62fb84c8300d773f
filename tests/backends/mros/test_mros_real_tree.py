"""Generated mROS applications build unedited in a real mROS v1.3 tree, as the generated README says.

With the tree found through MROS_ROOT (default ../shared/mros/mROS-1.3; skipped when absent): the TOPPERS
configurator built from the tree's source, a copy of the tree whose TCPROS buffers are raised to what the
applications state (mros.tcpros_header_max), and in it the RB-1 application and the feature application
(nested types, fixed and variable arrays, arrays of messages, constants, time, a same-board loop; built
with a robot namespace and a hooks file of the user's) copied to `mros_ws/<package>/` and built with `make`
— the tree's own Mbed, mROS and TOPPERS/ASP makefiles, the untouched upstream ros.cpp, Debian's
arm-none-eabi toolchain and newlib's libstdc++ — to `asp.bin`; the configurator's last pass checks the
image ("check complete"). Both builds run once per test session.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

from tests.backends.mros import apps, build, fixtures, real_tree
from tests.tools import require_ok

shared_root = fixtures.shared_root


@pytest.fixture(scope="session", autouse=True)
def _real_tree() -> None:
    """The tree is reference material beside the repository (skipped without it, as the README says); the
    tools that build it are required (tests/tools.py). Session-scoped: checked before `built`, which is."""
    tree = real_tree.tree_problem()
    if tree is not None:
        pytest.skip(tree)
    require_ok(real_tree.problem())


APPS = {"rb1": apps.rb1, "features": apps.features}
#: code of the user's own, next to the feature application (the README's way: make TD2A_USER_CXXOBJS=...):
#: a hook that replaces the weak default, and a header-stamp hook that uses time
USER_HOOKS = {
    "features": (
        "td2a_user_hooks.cpp",
        '#include "adaptor_hooks.h"\n'
        "bool adaptor_hooks::fill_stamp(std_msgs::Header &msg)\n"
        "{\n"
        "    msg.seq += 1u;\n"
        "    msg.stamp.sec = 1700000000u;\n"
        '    msg.frame_id = "base_link";\n'
        "    return true;\n"
        "}\n",
    )
}


def _tcpros_max() -> int:
    return int(dict(apps.TREE_LIMITS)["mros.tcpros_header_max"])


@pytest.fixture(scope="session")
def built(shared_root: Path) -> dict[str, Any]:
    """Both applications built in one copy of the tree (one after the other: the makefiles write the Mbed
    objects into the tree); per application the make output, its image sizes and whether its files stayed
    as generated."""
    generated = {name: make_app() for name, make_app in APPS.items()}
    for app in generated.values():
        assert not app.diags.has_errors, [(d.code, d.message) for d in app.diags.errors()]
    key = "real-" + build.digest([], str(real_tree.root()), *(d for a in generated.values() for _, d in _files(a)))

    def make(out: Path) -> None:
        tree = real_tree.tree_copy(out / "mROS", _tcpros_max())
        results = {}
        for name, app in generated.items():
            for rel, data in app.tree:  # as the README says: the directory, unedited, at mros_ws/<package>/
                path = tree / "mros_ws" / rel
                path.parent.mkdir(parents=True, exist_ok=True)
                path.write_bytes(data)
            app_dir = tree / "mros_ws" / app.root
            args = []
            if name in USER_HOOKS:
                source, code = USER_HOOKS[name]
                (app_dir / source).write_text(code)
                args = [f"TD2A_USER_CXXOBJS={Path(source).stem}.o", "TD2A_ROBOT_NAMESPACE=rb1_base"]
            log = real_tree.make(app_dir, *args)
            unchanged = all((tree / "mros_ws" / rel).read_bytes() == data for rel, data in app.tree)
            results[name] = {
                # the configurator's last pass, over the linked image, ends with "check complete"
                "checked": "--pass 3" in log and "check complete" in log[log.index("--pass 3") :],
                "bin": (app_dir / "asp.bin").is_file() and (app_dir / "asp.bin").stat().st_size > 0,
                "size": real_tree.image_size(app_dir / "asp.elf"),
                "unchanged": unchanged,
                "objects": build.size([app_dir / "app.o"]),
                # the user's hook replaced the weak default (the symbol comes from the user's object)
                "user_hook": name not in USER_HOOKS
                or "fill_stamp" in build.run(["arm-none-eabi-nm", "-C", str(app_dir / "td2a_user_hooks.o")]),
            }
        (out / "results.json").write_text(json.dumps(results))
        build.run(["rm", "-rf", str(out / "mROS")])

    results: dict[str, Any] = json.loads((build.shared(shared_root, key, make) / "results.json").read_text())
    return results


def _files(app: apps.App) -> list[tuple[str, str]]:
    return [(rel, data.decode("utf-8", "replace")) for rel, data in app.tree]


@pytest.mark.parametrize("name", list(APPS))
def test_the_application_builds_unedited_to_asp_bin(name: str, built: dict[str, Any]) -> None:
    result = built[name]
    assert result["checked"], "the configurator's --pass 3 did not say 'check complete'"
    assert result["bin"], "no asp.bin"
    assert result["unchanged"], "the build changed generated files"
    assert result["user_hook"]
    text, data, bss = result["size"]
    assert text > 100_000 and bss > 0  # a whole image: ASP, Mbed, lwIP, mROS and the adaptor
    # the application's object is in it (the adaptor's own code: tasks, components, message copies)
    assert next(iter(result["objects"].values()))[0] > 0
    print(f"{name}: asp.elf text {text} data {data} bss {bss}; app.o {result['objects']}")

"""Consistency lint of an mROS application's task configuration (pure Python, no TOPPERS configurator).

mROS's main task activates every entry of `mros_usr_task_table[MROS_USR_TASK_NUM]`; TOPPERS creates the tasks
from the `CRE_TSK` lines of `app.cfg`, whose entry functions `app.h` declares `extern "C"`. The four must
match exactly: the same task ids in `app.cfg` and in the table, as many as `MROS_USR_TASK_NUM` says, and the
same entry functions in `app.cfg` and `app.h`.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass

_COMMENTS = re.compile(r"/\*.*?\*/|//[^\n]*", re.S)
_CRE_TSK = re.compile(r"\bCRE_TSK\s*\(\s*(\w+)\s*,\s*\{\s*[^,{}]+,\s*[^,{}]+,\s*(\w+)\s*,")
_CRE_SEM = re.compile(r"\bCRE_SEM\s*\(\s*(\w+)\s*,")
_TABLE = re.compile(r"\bmros_usr_task_table\s*\[[^\]]*\]\s*=\s*\{([^}]*)\}")
_TASK_NUM = re.compile(r"^\s*#\s*define\s+MROS_USR_TASK_NUM\s+\(?\s*(\d+)\s*\)?\s*$", re.M)
_EXTERN_C = re.compile(r'extern\s+"C"\s*\{(.*?)\n\}', re.S)
_ENTRY = re.compile(r"\bvoid\s+(\w+)\s*\(\s*intptr_t\s+\w*\s*\)\s*;")

APP_CFG = "app.cfg"
APP_H = "app.h"
USR_CONFIG_H = "mros_config/mros_usr_config.h"
USR_CONFIG_C = "mros_config/mros_usr_config.c"
CHECKED = (APP_CFG, APP_H, USR_CONFIG_H, USR_CONFIG_C)


@dataclass(frozen=True)
class TaskConfig:
    """What each of the four places says about the user tasks."""

    cfg_tasks: tuple[tuple[str, str], ...]  # (id, entry) per CRE_TSK, in order
    cfg_semaphores: tuple[str, ...]
    table: tuple[str, ...]
    task_num: int | None
    entries: tuple[str, ...]  # extern "C" task entries of app.h


def _strip(text: str) -> str:
    return _COMMENTS.sub(" ", text)


def parse(app_cfg: str, app_h: str, usr_config_h: str, usr_config_c: str) -> TaskConfig:
    cfg = _strip(app_cfg)
    table = _TABLE.search(_strip(usr_config_c))
    num = _TASK_NUM.search(_strip(usr_config_h))
    entries = [e for block in _EXTERN_C.findall(_strip(app_h)) for e in _ENTRY.findall(block)]
    return TaskConfig(
        cfg_tasks=tuple((m.group(1), m.group(2)) for m in _CRE_TSK.finditer(cfg)),
        cfg_semaphores=tuple(_CRE_SEM.findall(cfg)),
        table=tuple(x.strip() for x in table.group(1).split(",") if x.strip()) if table else (),
        task_num=int(num.group(1)) if num else None,
        entries=tuple(entries),
    )


def problems(files: Mapping[str, str]) -> list[str]:
    """Every inconsistency between app.cfg, app.h and mros_config/mros_usr_config.{h,c} (paths relative to
    the application directory); an empty list when they agree."""
    missing = [p for p in CHECKED if p not in files]
    if missing:
        return [f"missing {p}" for p in missing]
    conf = parse(files[APP_CFG], files[APP_H], files[USR_CONFIG_H], files[USR_CONFIG_C])
    out = []
    ids = [t for t, _ in conf.cfg_tasks]
    cfg_entries = [e for _, e in conf.cfg_tasks]
    for what, seq in (("CRE_TSK id in app.cfg", ids), ("entry in mros_usr_task_table", conf.table)):
        dups = sorted({x for x in seq if seq.count(x) > 1})
        if dups:
            out.append(f"duplicate {what}: {', '.join(dups)}")
    if sorted(ids) != sorted(conf.table):
        out.append(f"app.cfg creates tasks {sorted(ids)} but mros_usr_task_table lists {sorted(conf.table)}")
    if conf.task_num is None:
        out.append("MROS_USR_TASK_NUM is not defined in mros_config/mros_usr_config.h")
    elif conf.task_num != len(conf.table) or conf.task_num != len(ids):
        out.append(
            f"MROS_USR_TASK_NUM is {conf.task_num}, but app.cfg creates {len(ids)} tasks and "
            f"mros_usr_task_table has {len(conf.table)} entries"
        )
    if sorted(cfg_entries) != sorted(conf.entries):
        out.append(f"app.cfg's task entries {sorted(cfg_entries)} differ from app.h's {sorted(conf.entries)}")
    return out


def kernel_cfg_h(app_cfg: str, first_id: int = 1) -> str:
    """A `kernel_cfg.h` as the TOPPERS configurator would number the application's objects (for host builds
    of generated code; the real one also holds mROS's own objects)."""
    conf = _strip(app_cfg)
    lines = ["/* kernel object ids of the application (host stand-in for the TOPPERS configurator) */"]
    lines += [f"#define {tid} {first_id + i}" for i, (tid, _) in enumerate(_CRE_TSK.findall(conf))]
    lines += [f"#define {sid} {first_id + i}" for i, sid in enumerate(_CRE_SEM.findall(conf))]
    return "\n".join(lines) + "\n"

"""Behaviour harness: a generated application's tasks on pthreads over the loopback bus (tests/backends/mros/mros_api).

The host program links app.cpp, the ros.cpp stand-in, the bus and mros_usr_config.c with a main and strong
hook definitions made here from the backend's plan (so they replace the weak defaults). Line protocol:

    FILL <prop> <hex>     the fill hook of <prop> deserialises <hex> into its message and returns true
    RUNPUB <n>            run the publisher task until its n-th Rate::sleep
    RUNSUB                run the subscriber task (the stub ros::spin returns)
    ENDPOINTS             `node,topic,datatype,md5,queue,pub` per advertise/subscribe, ';'-separated
    INJECT <topic> <hex>  deliver a message to the subscribers of <topic>: how many callbacks ran
    GET <prop>            get_<prop>_value: `none` or the hex of the copy
    GETVALUE <prop>       get_value() of <prop>'s component
    HOOK <prop>           `<calls> <hex of the last message>` seen by on_<prop>
    PUBLISH <prop> <hex>  publish_<prop>_Msg with that message: 1 or 0
    PUBLISHED             `topic,hex` per publish (with mROS's length prefix), ';'-separated
    PROBLEMS / LOG        what the stubs detected / syslog lines, ';'-separated
"""

from __future__ import annotations

import subprocess
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from tests.backends.mros import build

_HEAD = """/* td2adaptor test harness: behaviour of a generated mROS application over the loopback bus. */
#include <pthread.h>
#include <iostream>
#include <map>
#include <sstream>
#include <string>
#include "app.h"
#include "adaptor_components.h"
#include "mros_stub_bus.h"

static std::string unhex(const std::string &h) {
    std::string out;
    for (size_t i = 0; i + 1 < h.size(); i += 2) out += (char)std::stoi(h.substr(i, 2), nullptr, 16);
    return out;
}
static std::string hex(const std::string &b) {
    static const char *d = "0123456789abcdef";
    std::string out;
    for (unsigned char c : b) { out += d[c >> 4]; out += d[c & 15]; }
    return out;
}
template <class M> static std::string encode(const M &m) {
    std::string buf((size_t)m.dataSize(), '\\0');
    char *p = &buf[0];
    m.td2a_write(p);
    return hex(buf);
}
template <class M> static void decode(const std::string &h, M &m) {
    std::string b = unhex(h);
    b.push_back('\\0');
    char *p = &b[0];
    m.deserialize(p);
}
static std::map<std::string, std::string> g_fill;
static std::map<std::string, int> g_hook_calls;
static std::map<std::string, std::string> g_hook_last;
static void *run_task(void *entry) { ((void (*)(intptr_t))entry)(0); return nullptr; }
static void run(void (*entry)(intptr_t)) {
    pthread_t t;
    pthread_create(&t, nullptr, run_task, (void *)entry);
    pthread_join(t, nullptr);
}

namespace adaptor_hooks {
"""

_MAIN = """
int main() {
    std::string line;
    while (std::getline(std::cin, line)) {
        std::istringstream in(line);
        std::string cmd, a, b;
        in >> cmd >> a >> b;
        std::ostringstream out;
        if (cmd == "FILL") {
            g_fill[a] = b;
        } else if (cmd == "RUNPUB") {
@RUNPUB@
        } else if (cmd == "RUNSUB") {
@RUNSUB@
        } else if (cmd == "ENDPOINTS") {
            for (const auto &e : stub::endpoints())
                out << e.node << ',' << e.topic << ',' << e.datatype << ',' << e.md5 << ',' << e.queue_size << ','
                    << e.publisher << ';';
        } else if (cmd == "INJECT") {
            out << stub::inject(a, unhex(b));
        } else if (cmd == "HOOK") {
            out << g_hook_calls[a] << ' ' << g_hook_last[a];
        } else if (cmd == "PUBLISHED") {
            for (const auto &s : stub::published()) out << s.topic << ',' << hex(s.bytes) << ';';
        } else if (cmd == "PROBLEMS") {
            for (const auto &p : stub::problems()) out << p << ';';
        } else if (cmd == "LOG") {
            for (const auto &l : stub::log_lines()) out << l << ';';
@COMMANDS@
        } else {
            out << "unknown command";
        }
        std::cout << out.str() << '\\n' << std::flush;
    }
}
"""


def harness_source(context: dict[str, Any]) -> str:
    """The C++17 main of the behaviour harness for an application plan's context."""
    lines = [_HEAD]
    for p in context["publishers"]:
        lines.append(
            f"bool {p.hook}({p.msg.qualified} &msg) {{\n"
            f'    auto it = g_fill.find("{p.prop}");\n'
            f"    if (it == g_fill.end()) return false;\n"
            f"    decode(it->second, msg);\n"
            f"    return true;\n}}"
        )
    for s in context["subscribers"]:
        lines.append(
            f"void {s.hook}(const {s.msg.qualified} &msg) {{\n"
            f'    ++g_hook_calls["{s.prop}"];\n'
            f'    g_hook_last["{s.prop}"] = encode(msg);\n}}'
        )
    lines.append("}  // namespace adaptor_hooks")
    commands = []
    for c in context["components"]:
        for s in c.subscribers:
            commands.append(
                f'        }} else if (cmd == "GET" && a == "{s.prop}") {{\n'
                f"            {s.msg.qualified} m;\n"
                f'            out << (adaptor::{c.instance}.{s.getter}(m) ? encode(m) : std::string("none"));'
            )
        if c.single is not None:
            commands.append(
                f'        }} else if (cmd == "GETVALUE" && a == "{c.single.prop}") {{\n'
                f"            {c.single.msg.qualified} m;\n"
                f'            out << (adaptor::{c.instance}.get_value(m) ? encode(m) : std::string("none"));'
            )
        for p in c.publishers:
            commands.append(
                f'        }} else if (cmd == "PUBLISH" && a == "{p.prop}") {{\n'
                f"            {p.msg.qualified} m;\n"
                f"            decode(b, m);\n"
                f"            out << adaptor::{c.instance}.{p.publish}(m);"
            )
    entries = {t.kind: t.entry for t in context["tasks"]}
    runpub = (
        f"            stub::set_sleep_limit(std::stoi(a));\n            run({entries['pub']});"
        if "pub" in entries
        else ""
    )
    runsub = f"            run({entries['sub']});" if "sub" in entries else ""
    main = _MAIN.replace("@RUNPUB@", runpub).replace("@RUNSUB@", runsub).replace("@COMMANDS@", "\n".join(commands))
    lines.append(main)
    return "\n".join(lines) + "\n"


def build_harness(app: Path, context: dict[str, Any], out: Path, defines: Sequence[str] = ()) -> Path:
    """Compile and link the behaviour harness of the application at `app` into `out`."""
    out.mkdir(parents=True, exist_ok=True)
    main = out / "loopback_main.cpp"
    main.write_text(harness_source(context))
    objs = build.host_objects(app, out, defines=defines)
    main_obj = out / "loopback_main.o"
    build.run(
        [
            build.HOST_CXX,
            "-std=gnu++17",
            "-g",
            "-O1",
            *defines,
            *build.includes(app),
            "-c",
            str(main),
            "-o",
            str(main_obj),
        ]
    )
    exe = out / "loopback"
    build.run([build.HOST_CXX, *map(str, [*objs, main_obj]), "-o", str(exe), "-lpthread"])
    return exe


class Loopback:
    """A running behaviour harness."""

    def __init__(self, exe: Path) -> None:
        self.proc = subprocess.Popen([str(exe)], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)

    def ask(self, line: str) -> str:
        assert self.proc.stdin is not None and self.proc.stdout is not None
        self.proc.stdin.write(line + "\n")
        self.proc.stdin.flush()
        reply = self.proc.stdout.readline()
        assert reply, f"loopback harness died on: {line[:200]}"
        return reply.rstrip("\n")

    def items(self, line: str) -> list[str]:
        return [x for x in self.ask(line).split(";") if x]

    def close(self) -> None:
        for stream in (self.proc.stdin, self.proc.stdout):
            if stream is not None:
                stream.close()
        self.proc.wait(timeout=30)

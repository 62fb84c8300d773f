"""ROS 1 message definition texts and md5 sums, computed the way genmsg/genpy do.

rospy and rosbag put these in connection headers; a mismatch makes ROS 1 peers refuse each other, so the
texts follow genmsg exactly: constants hashed as written, nested messages replaced by their md5.
"""

from __future__ import annotations

import hashlib
from collections.abc import Callable, Iterable

from td2adaptor.model import FieldType, MessageDef
from td2adaptor.rostypes.names import ros1_name


class Ros1Texts:
    """Definition texts and (memoised) md5 sums over the messages a lookup function knows."""

    def __init__(
        self,
        message: Callable[[str], MessageDef | None],
        written_constants: Callable[[str], tuple[str, ...] | None],
    ) -> None:
        self._message = message
        self._written_constants = written_constants
        self._md5s: dict[str, str] = {}

    def _constant_texts(self, name: str, msg: MessageDef) -> Iterable[str]:
        found = self._written_constants(name)
        if found is not None:
            return found
        return (f"{c.value}" for c in msg.constants)

    def _require(self, name: str, user: str) -> MessageDef:
        msg = self._message(name)
        if msg is None:
            raise KeyError(f"{user} uses unknown type {name}" if user != name else f"unknown type {name}")
        return msg

    def own_text(self, name: str) -> str:
        """The ROS 1 text of one message without its dependencies (`time`, `pkg/Name` spellings)."""
        msg = self._require(name, name)
        lines = [f"{c.type} {c.name}={t}" for c, t in zip(msg.constants, self._constant_texts(name, msg), strict=True)]
        for fld in msg.fields:
            ftype = fld.type
            spelled = FieldType(ros1_name(ftype.base), False, ftype.array, ftype.length) if ftype.is_message else ftype
            lines.append(f"{spelled} {fld.name}")
        return "".join(f"{line}\n" for line in lines)

    def md5_text(self, name: str) -> str:
        """genmsg's md5 text: constants as written, then fields, nested messages replaced by their md5."""
        msg = self._require(name, name)
        lines = [f"{c.type} {c.name}={t}" for c, t in zip(msg.constants, self._constant_texts(name, msg), strict=True)]
        for fld in msg.fields:
            if fld.type.is_message:
                self._require(fld.type.base, name)
                lines.append(f"{self.md5(fld.type.base)} {fld.name}")
            else:
                lines.append(f"{fld.type} {fld.name}")
        return "\n".join(lines)

    def md5(self, name: str) -> str:
        found = self._md5s.get(name)
        if found is None:
            found = hashlib.md5(self.md5_text(name).encode()).hexdigest()
            self._md5s[name] = found
        return found

    def service(self, request: str, response: str) -> tuple[str, str]:
        """Request and response texts around `---`, and genpy's service md5 (over both md5 texts)."""
        digest = hashlib.md5((self.md5_text(request) + self.md5_text(response)).encode()).hexdigest()
        return f"{self.own_text(request)}---\n{self.own_text(response)}", digest

    def message(self, name: str) -> tuple[str, str]:
        """The message's text, then each message it uses after a `====...` line and `MSG: pkg/Name`."""
        digest = self.md5(name)
        deps: dict[str, None] = {}

        def collect(msg_name: str) -> None:
            for fld in self._require(msg_name, msg_name).fields:
                if fld.type.is_message and fld.type.base not in deps:
                    deps[fld.type.base] = None
                    collect(fld.type.base)

        collect(name)
        parts = [self.own_text(name)]
        parts += [f"{'=' * 80}\nMSG: {ros1_name(dep)}\n{self.own_text(dep)}" for dep in deps]
        return "".join(parts), digest

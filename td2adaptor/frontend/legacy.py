"""The reference system's pre-TD configuration (`service.json` / `topic.json` with `RosClasses`).

It is lowered by turning it into a reference-dialect TD in memory (the mapping the reference system itself
used: `ClassName` → `ros:codeGenerator:class`, client/reference name → affordance key, other keys →
`ros:<key>` in `forms[0]`), so one extractor serves both. Pointers are mapped back to the config files so
diagnostics point at what the user wrote.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any

from td2adaptor.diagnostics import Diagnostic, Diagnostics, pointer_join
from td2adaptor.frontend.extract import REFERENCE_CLASS_KEY
from td2adaptor.frontend.jsonsrc import JsonDocument

LEGACY_TITLE = "ROS Edge Node"

_SERVICE_KEYS = ("serviceName", "serviceType", "serviceRequestType", "serviceResponseType")
_TOPIC_KEYS = ("Role", "TopicName", "TopicType", "MessageType")
_CLIENT_LISTS = ("ServceClients", "ServiceClients")  # the reference files spell it "ServceClients"


def is_legacy(data: Any) -> bool:
    return isinstance(data, dict) and "RosClasses" in data


@dataclass
class LegacyInput:
    """The synthetic reference-dialect TD and where each of its pointers came from."""

    td: dict[str, Any]
    docs: list[JsonDocument]
    origins: dict[str, tuple[int, str]] = field(default_factory=dict)  # td pointer → (doc index, pointer)

    def remap(self, diag: Diagnostic) -> tuple[Diagnostic, JsonDocument | None]:
        """The diagnostic re-pointed into the config file it is about (longest matching prefix)."""
        ptr = diag.pointer
        while True:
            if ptr in self.origins:
                index, origin = self.origins[ptr]
                doc = self.docs[index]
                return replace(diag, pointer=origin + diag.pointer[len(ptr) :], file=doc.name), doc
            if not ptr:
                return diag, self.docs[0] if self.docs else None
            ptr = ptr.rsplit("/", 1)[0]


def to_reference_td(docs: Sequence[JsonDocument], diags: Diagnostics) -> LegacyInput:
    """Merge one or more legacy config files into a reference-dialect TD."""
    out = LegacyInput(
        {
            "title": LEGACY_TITLE,
            "securityDefinitions": {"nosec_sc": {"scheme": "nosec"}},
            "security": ["nosec_sc"],
        },
        list(docs),
    )
    groups: dict[str, dict[str, Any]] = {}  # "actions"/"properties" in order of first use
    for index, doc in enumerate(docs):
        local = Diagnostics()
        classes = doc.data.get("RosClasses") if isinstance(doc.data, dict) else None
        if not isinstance(classes, list):
            local.error("MIG701", "'RosClasses' must be a list of classes", "/RosClasses")
            classes = []
        for ci, cls in enumerate(classes):
            cptr = pointer_join("/RosClasses", ci)
            if not isinstance(cls, dict):
                local.error("MIG701", "each entry of 'RosClasses' must be an object", cptr)
                continue
            class_name = cls.get("ClassName")
            if not isinstance(class_name, str) or not class_name:
                local.error("MIG702", "'ClassName' is missing or not a string", pointer_join(cptr, "ClassName"))
                continue
            entries = [(k, "action", _SERVICE_KEYS, "serviceClientName") for k in _CLIENT_LISTS if k in cls]
            if "Topics" in cls:
                entries.append(("Topics", "property", _TOPIC_KEYS, "ReferenceName"))
            if not entries:
                local.warning("MIG703", f"class {class_name!r} has neither 'ServceClients' nor 'Topics'", cptr)
            for list_key, kind, keys, name_key in entries:
                items = cls[list_key]
                lptr = pointer_join(cptr, list_key)
                if not isinstance(items, list):
                    local.error("MIG701", f"{list_key!r} must be a list", lptr)
                    continue
                for ii, item in enumerate(items):
                    iptr = pointer_join(lptr, ii)
                    if not isinstance(item, dict):
                        local.error("MIG701", f"each entry of {list_key!r} must be an object", iptr)
                        continue
                    name = item.get(name_key)
                    if not isinstance(name, str) or not name:
                        local.error("MIG702", f"{name_key!r} is missing or not a string", pointer_join(iptr, name_key))
                        continue
                    group = "actions" if kind == "action" else "properties"
                    target = groups.setdefault(group, {})
                    tptr = pointer_join("", group, name)
                    if name in target:
                        # the reference generated both (e.g. topic-test.json's Subscriber and Publisher `door`);
                        # a TD has one affordance per name, so the later one is renamed
                        renamed = next(f"{name}{n}" for n in range(2, len(target) + 3) if f"{name}{n}" not in target)
                        local.warning(
                            "MIG704",
                            f"{kind} name {name!r} is used twice: this one becomes {renamed!r}",
                            pointer_join(iptr, name_key),
                            "rename it in the config file, or in the TD that 'td2adaptor migrate' writes",
                        )
                        name = renamed
                        tptr = pointer_join("", group, name)
                    form: dict[str, Any] = {"op": ["invokeaction"] if kind == "action" else ["readproperty"]}
                    form["subprotocol"] = "ros"
                    out.origins[tptr] = (index, iptr)
                    out.origins[pointer_join(tptr, REFERENCE_CLASS_KEY)] = (
                        index,
                        pointer_join(cptr, "ClassName"),
                    )
                    out.origins[pointer_join(tptr, "forms", 0)] = (index, iptr)
                    for key in keys:
                        if key in item:
                            form["ros:" + key] = item[key]
                            out.origins[pointer_join(tptr, "forms", 0, "ros:" + key)] = (
                                index,
                                pointer_join(iptr, key),
                            )
                    target[name] = {REFERENCE_CLASS_KEY: class_name, "forms": [form]}
        for d in local:
            diags.append(doc.locate(replace(d, file=doc.name)))
    out.td.update(groups)
    return out

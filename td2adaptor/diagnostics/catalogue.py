"""Every diagnostic code td2adaptor reports: its severity, what it means and, where one helps, a hint.

One catalogue, so that a code cannot be reported without being documented (`Diagnostics.add` refuses unknown
codes), `docs/diagnostics.md` is generated from it and `td2adaptor explain CODE` can print an entry. A test
checks that the codes here are exactly the codes the source reports.

The stages of the pipeline are listed here; a backend declares its own stage and codes beside its code and
adds them with `register` when its package is imported (`backends/mros/diagnostics.py`; a plug-in backend
the same way), so that this layer never has to know which backends exist.

The hints here are general advice for the documentation; the hint a diagnostic carries is the one its call
site gives (often more specific), so reported output does not depend on this file.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType

from td2adaptor.diagnostics.severity import Severity

_E, _W, _I = Severity.ERROR, Severity.WARNING, Severity.INFO


@dataclass(frozen=True)
class Stage:
    """A group of codes sharing a prefix (`TD0`, `ROS4`, ...): one pipeline stage or one backend."""

    prefix: str
    title: str
    modules: str
    backend: str | None = None  # the backend whose own codes these are (a backend's stage, see `register`)


@dataclass(frozen=True)
class Entry:
    """One code. `severities` lists every severity it is reported with, the default first; `when` says which."""

    code: str
    severities: tuple[Severity, ...]
    meaning: str
    hint: str | None = None
    when: str | None = None

    @property
    def severity(self) -> Severity:
        """The severity the code is reported with unless `when` says otherwise."""
        return self.severities[0]

    @property
    def stage(self) -> Stage:
        return stage_of(self.code)

    def severity_text(self) -> str:
        """`error`, or e.g. `error; warning under --partial` for a code reported with several severities."""
        if self.when is None:
            return "/".join(s.value for s in self.severities)
        return f"{self.severity.value}; {self.when}"


STAGES: tuple[Stage, ...] = (
    Stage("TD0", "Reading the input", "frontend/jsonsrc, compiler/pipeline"),
    Stage("TD1", "TD and Thing Model conformance", "frontend/conformance"),
    Stage("TD2", "Vocabulary and JSON-LD", "frontend/terms, frontend/jsonld"),
    Stage("TM3", "Thing Models", "frontend/thingmodel, cli"),
    Stage("ROS4", "ROS binding", "frontend/extract, lowering/lower"),
    Stage("TY5", "ROS interface types", "rostypes"),
    Stage("XC6", "Data schemas against ROS messages", "lowering/crosscheck"),
    Stage("MIG7", "Legacy input and migration", "frontend/legacy, frontend/migrate"),
    Stage("SCF1", "Scaffolding a TD from a robot", "scaffold, cli/scaffold"),
    Stage("GEN8", "Generation", "compiler/build, generation, backends/rclpy, backends/rospy, backends/events"),
    Stage("CFG9", "Project configuration", "generation/targets, api"),
)

_ENTRIES: tuple[Entry, ...] = (
    # -- TD0: reading the input --------------------------------------------------------------------------
    Entry("TD000", (_E,), "input cannot be read (missing file, no input given)", "check the path"),
    Entry("TD001", (_E,), "input is not valid UTF-8", "save the file as UTF-8"),
    Entry("TD002", (_W,), "input starts with a byte order mark", "save the file as UTF-8 without a BOM"),
    Entry("TD003", (_E,), "duplicate key in a JSON object", "JSON parsers silently keep only the last one"),
    Entry("TD004", (_E,), "invalid JSON"),
    Entry("TD005", (_E,), "invalid JSON (a number or value JSON cannot hold)"),
    Entry("TD006", (_E,), "input larger than the size limit", "raise the limit with --max-bytes"),
    Entry("TD007", (_E,), "JSON nested too deeply to process"),
    Entry("TD008", (_E,), "several inputs given that are not all legacy RosClasses files"),
    Entry("TD009", (_E,), "a Thing Description is not a JSON object"),
    Entry("TD010", (_E,), "more affordances than the limit", "raise it with --max-affordances"),
    Entry("TD011", (_E,), "string with an unpaired surrogate escape, which is not Unicode text"),
    # -- TD1: conformance (schema violations and cross-references are errors, advice warnings) --------------
    Entry("TD100", (_E,), "value violates the TD/TM schema"),
    Entry("TD101", (_E,), "required member missing"),
    Entry("TD102", (_E,), "value has the wrong JSON type"),
    Entry("TD103", (_E,), "value not allowed (not one of the permitted values, or a forbidden value)"),
    Entry("TD104", (_E,), "malformed value (date-time, IRI, URI template or pattern)"),
    Entry("TD105", (_E,), "array or object is empty, too small or has duplicate items"),
    Entry("TD106", (_E,), "@context is not a TD 1.0/1.1 context", "start @context with the TD 1.1 context URI"),
    Entry("TD110", (_E,), "security scheme name is not defined in securityDefinitions"),
    Entry("TD111", (_E,), "combo security scheme refers to an undefined scheme or to itself"),
    Entry("TD112", (_E,), "additionalResponses schema is not defined in schemaDefinitions"),
    Entry("TD113", (_E,), "more than one link with rel 'type'"),
    Entry("TD114", (_E,), "tm:optional entry does not resolve to an interaction affordance"),
    Entry("TD120", (_W,), "enum and const used together"),
    Entry("TD121", (_W,), "object schema without properties"),
    Entry("TD122", (_W,), "array schema without items"),
    Entry("TD123", (_W,), "readOnly and writeOnly are both true"),
    Entry("TD124", (_W,), "form operation contradicts readOnly/writeOnly"),
    Entry("TD125", (_W,), "multi-language maps use different sets of languages"),
    Entry("TD126", (_W,), "malformed BCP 47 language tag"),
    Entry("TD127", (_W,), "apikey in 'uri' has no matching URI template variable in href"),
    Entry("TD128", (_W,), "apikey in 'uri' name is also declared in uriVariables"),
    # -- TD2: vocabulary and JSON-LD ---------------------------------------------------------------------
    Entry("TD201", (_W,), "unknown term: not a TD 1.1 term at this position, nor a compact IRI"),
    Entry("TD202", (_W,), "compact IRI prefix not declared in @context", "declare the prefix in @context"),
    Entry("TD203", (_W,), "suspicious data-schema member name (contains a colon but is not a compact IRI)"),
    Entry("TD251", (_W,), "remote JSON-LD context not available offline; not fetched, expansion continues without it"),
    Entry("TD252", (_E,), "JSON-LD syntax error"),
    Entry("TD253", (_E,), "JSON-LD processing failed unexpectedly"),
    # -- TM3: Thing Models -------------------------------------------------------------------------------
    Entry("TM300", (_E,), "the document to instantiate is not a Thing Model"),
    Entry("TM301", (_E,), "placeholders without a value", "give each with --set NAME=VALUE or in a --values file"),
    Entry("TM302", (_I,), "runtime placeholders left in place"),
    Entry("TM303", (_I,), "placeholder values not used by the model"),
    Entry("TM304", (_E,), "two keys of an object became equal after placeholder substitution"),
    Entry("TM305", (_E,), "malformed --set item", "e.g. --set MAX_SPEED=1.5"),
    Entry("TM306", (_W,), "placeholder given more than once"),
    Entry("TM307", (_E,), "placeholder map file cannot be read or parsed"),
    Entry("TM308", (_E,), "placeholder map has the wrong shape", 'e.g. {"robotName": "rb1_base_a"}'),
    Entry("TM309", (_E,), "model too deeply nested to process"),
    Entry("TM310", (_E,), "referenced Thing Model file not found"),
    Entry(
        "TM311",
        (_E, _W),
        "remote Thing Model not fetched",
        "download the model and refer to it by a relative path",
        "warning when checking a TD against its model",
    ),
    Entry("TM312", (_E,), "tm:extends cycle"),
    Entry("TM313", (_E,), "malformed tm:extends link"),
    Entry("TM314", (_W,), "extended document is not a Thing Model"),
    Entry("TM320", (_E,), "malformed tm:ref", 'e.g. "tm:ref": "base.tm.json#/properties/battery"'),
    Entry("TM321", (_E,), "tm:ref target not found"),
    Entry("TM322", (_E,), "tm:ref cycle"),
    Entry("TM323", (_E,), "too many tm:ref imports"),
    Entry("TM330", (_E,), "malformed tm:optional"),
    Entry("TM331", (_E,), "tm:optional entry does not point to a whole affordance"),
    Entry("TM332", (_E,), "selected optional affordance is not declared optional"),
    Entry("TM333", (_I,), "optional affordances left out"),
    Entry("TM340", (_I,), "@context adjusted for a Thing Description"),
    Entry("TM341", (_I,), "no security in the model: nosec added"),
    Entry("TM342", (_W,), "model has only part of the security configuration"),
    Entry("TM343", (_W,), "affordance without forms", "add the forms to the Thing Model"),
    Entry("TM344", (_W,), "model has no title", "add a title to the Thing Model"),
    Entry("TM345", (_I,), "instance version added"),
    Entry("TM346", (_W,), "version is not an object", 'e.g. "version": {"instance": "1.0.0"}'),
    Entry("TM347", (_W,), "tm:submodel links are not instantiated", "instantiate each submodel on its own"),
    Entry("TM348", (_I,), "Thing Model terms dropped"),
    Entry("TM349", (_I,), "no rel=type link added"),
    Entry("TM350", (_W,), "linked Thing Model not fetched"),
    Entry("TM351", (_E,), "linked Thing Model cannot be used"),
    Entry("TM352", (_E,), "affordance of the linked Thing Model missing in the TD"),
    Entry("TM353", (_E,), "affordance data type differs from the linked Thing Model"),
    # -- ROS4: ROS binding -------------------------------------------------------------------------------
    Entry("ROS400", (_W,), "no affordance is bound to ROS: nothing to generate", "see docs/binding.md"),
    Entry("ROS401", (_E,), "action not bound to a ROS service", "add a form with rosv:name and rosv:type"),
    Entry("ROS402", (_E,), "affordance with more than one ROS form"),
    Entry("ROS403", (_E,), "ROS form term missing"),
    Entry("ROS404", (_E,), "ROS form term is not a non-empty string"),
    Entry("ROS405", (_E,), "invalid rosv:interface"),
    Entry("ROS406", (_E,), "ROS interface kind does not fit the affordance kind"),
    Entry("ROS407", (_E,), "invalid or unfitting ROS role"),
    Entry("ROS408", (_E,), "invalid QoS, latch or queue size"),
    Entry("ROS409", (_E,), "component class name is not a non-empty string"),
    Entry("ROS410", (_E,), "invalid ROS name"),
    Entry("ROS411", (_W,), "reference system's namespace placeholder used in a ROS name"),
    Entry(
        "ROS412", (_W,), "empty href and no base (reference-dialect defect)", "'td2adaptor migrate' writes a ros: href"
    ),
    Entry("ROS413", (_W,), "href does not match rosv:name"),
    Entry("ROS414", (_E,), "one ROS name bound with two different types", "one ROS name has one type"),
    Entry("ROS415", (_W,), "contentType application/xml on JSON data (reference-dialect defect)"),
    Entry(
        "ROS416",
        (_W,),
        "a relative ROS name beside names under the robot namespace: robots of a fleet would share it",
        "write '/{{robotName}}/name', or '/name' if it is global",
    ),
    Entry("ROS420", (_E,), "not a ROS interface type name", "write it as pkg/msg/Name (srv, action)"),
    Entry("ROS421", (_E,), "type kind does not fit the ROS interface (msg for topics, srv for services)"),
    Entry("ROS422", (_W,), "declared class name does not match the ROS type"),
    Entry("ROS423", (_E,), "unknown ROS type", "add its definition with --interfaces DIR"),
    Entry(
        "ROS424",
        (_W, _E),
        "ROS type usable with one ROS version only (the other does not define it, or a type it uses, or cannot "
        "read its file): the other version's backends cannot use it",
        None,
        "error when neither version can use it",
    ),
    Entry("ROS427", (_W,), "type written in a ROS 1 or rosjava spelling", "write pkg/msg/Name (srv, action)"),
    Entry(
        "ROS428",
        (_I,),
        "a standard interface package the adaptors import at run time",
        "ROS 2: pip install ros-jazzy-<package>; ROS 1: apt install python3-<package>",
    ),
    Entry(
        "ROS429",
        (_E,),
        "a hidden type of a ROS 2 action (Name_SendGoal, Name_GetResult, Name_FeedbackMessage)",
        'bind the action itself: "rosv:interface": "action", "rosv:type": "pkg/action/Name"',
    ),
    Entry("ROS430", (_E,), "component name unusable as a class name", "use a CamelCase name"),
    Entry("ROS431", (_E,), "affordance name unusable in generated method names"),
    Entry("ROS432", (_E,), "package name is not a valid ROS package name"),
    Entry(
        "ROS433",
        (_E,),
        "interface type name too long: no file system could hold its definition file (255 bytes per name)",
        "give the type's real name",
    ),
    Entry("ROS440", (_I,), "procedure linkage derived from names", "'td2adaptor migrate' writes rosv:procedure"),
    Entry("ROS441", (_E,), "malformed rosv:procedure"),
    Entry("ROS442", (_E,), "procedure link target is not an action of the component"),
    Entry("ROS443", (_E,), "procedure links are inconsistent"),
    Entry("ROS444", (_E,), "invalid procedure missionId"),
    Entry(
        "ROS445",
        (_E,),
        "the edge node could not read a procedure's state",
        "name the response field holding the state with rosv:procedure `state` and `states`",
    ),
    Entry("ROS446", (_E,), "invalid procedure state mapping (state, states, message)"),
    Entry(
        "ROS447",
        (_W,),
        "a procedure's mission id cannot reach its query or cancel",
        "the edge node asks about the robot's current mission instead",
    ),
    Entry(
        "ROS448",
        (_W,),
        "a procedure without a query: only its start can be reported",
        "link a query action whose response carries the state",
    ),
    Entry(
        "ROS449",
        (_E,),
        "rosv:procedure on an action bound to a ROS action, which has its own goal states, feedback and cancel",
        "remove rosv:procedure",
    ),
    # -- TY5: ROS interface types ------------------------------------------------------------------------
    Entry("TY500", (_E,), "interface folder not found"),
    Entry("TY501", (_W,), "interface folder contains no .msg/.srv/.action files", "use <pkg>/msg/*.msg etc."),
    Entry(
        "TY502",
        (_E, _W),
        "interface package or file name is not a valid ROS name",
        None,
        "warning when the TD uses no type that needs the file",
    ),
    Entry(
        "TY503", (_E, _W), "interface file cannot be read", None, "warning when the TD uses no type that needs the file"
    ),
    Entry(
        "TY510",
        (_E, _W),
        "syntax error in interface file",
        "fields are `type name`, constants `type NAME=value`",
        "warning when the TD uses no type that needs the file",
    ),
    Entry("TY511", (_E, _W), "invalid field type", None, "warning when the TD uses no type that needs the file"),
    Entry("TY512", (_E, _W), "invalid constant", None, "warning when the TD uses no type that needs the file"),
    Entry(
        "TY513",
        (_E, _W),
        "duplicate field or constant name",
        None,
        "warning when the TD uses no type that needs the file",
    ),
    Entry(
        "TY514",
        (_E, _W),
        "wrong number of '---' separators for the file kind",
        None,
        "warning when the TD uses no type that needs the file",
    ),
    Entry("TY515", (_W,), "field default values are a ROS 2 feature; ignored for ROS 1"),
    Entry(
        "TY516", (_E, _W), "invalid field default value", None, "warning when the TD uses no type that needs the file"
    ),
    Entry("TY517", (_W,), "accepted by ROS 1 (genmsg) but rejected by ROS 2 (rosidl): a name or a separator line"),
    Entry(
        "TY520",
        (_E, _W),
        "field uses an undefined type",
        "add its definition",
        "warning when the TD uses no type that needs the file",
    ),
    Entry(
        "TY521",
        (_E, _W),
        "messages contain each other (recursive definition)",
        None,
        "warning when the TD uses no type that needs the file",
    ),
    Entry("TY530", (_W,), "user definition replaces a different typestore definition of the same name"),
    Entry("TY531", (_W,), "interface definition replaces a different earlier definition of the same name"),
    # -- XC6: data schemas against ROS messages ----------------------------------------------------------
    Entry("XC601", (_W,), "schema property is not a field of the message"),
    Entry("XC602", (_W,), "message fields missing from the schema"),
    Entry("XC603", (_W,), "misplaced field: a message field written beside `properties` instead of inside it"),
    Entry("XC604", (_W,), "JSON type does not match the ROS field type"),
    Entry("XC605", (_W,), "integer ROS field described as `number`"),
    Entry("XC606", (_W,), "time/duration written with the other ROS distribution's member names"),
    Entry("XC607", (_W,), "array length constraints contradict the ROS array size"),
    Entry("XC608", (_I,), "minItems on a ROS sequence, which may be empty"),
    Entry("XC609", (_W,), "enum values that are not constants of the message"),
    Entry("XC611", (_W,), "schema bounds exceed the range of the ROS type"),
    # -- MIG7: legacy input and migration ----------------------------------------------------------------
    Entry("MIG701", (_E,), "legacy RosClasses file: a list or object is malformed"),
    Entry("MIG702", (_E,), "legacy RosClasses file: a name is missing or not a string"),
    Entry("MIG703", (_W,), "legacy class with neither service clients nor topics"),
    Entry("MIG704", (_W,), "legacy RosClasses file: a name is used twice; the later one is renamed"),
    Entry("MIG710", (_I,), "migrate: links without href dropped"),
    Entry("MIG711", (_I,), "migrate: pre-recommendation @context replaced by the TD 1.1 context"),
    Entry("MIG712", (_I,), "migrate: epoch string written as a date-time"),
    # -- GEN8: generation --------------------------------------------------------------------------------
    Entry("GEN800", (_E,), "--package-name is not a valid ROS package name"),
    Entry("GEN801", (_E,), "generated path unsafe (absolute, '..', or through a symbolic link)"),
    Entry("GEN802", (_E,), "refusing to overwrite a file td2adaptor did not generate or that was edited", "--force"),
    Entry("GEN803", (_W,), "file no longer generated but edited by hand: kept"),
    Entry("GEN804", (_E,), "unknown or unavailable backend"),
    Entry(
        "GEN805",
        (_E,),
        "two inputs (TDs, RosClasses configurations) generate different contents for one file",
        "give them different package names",
    ),
    Entry(
        "GEN806",
        (_E,),
        "an output directory could not be written: nothing was changed",
        "free space or fix the permissions and run again",
    ),
    Entry(
        "GEN807",
        (_W,),
        "a backend that `all` brought in cannot represent the TD: skipped, the others are generated",
        "--partial generates what it can; name the backend with -b to see every problem",
    ),
    Entry("GEN808", (_E,), "a backend option names no known backend", "options are <backend>.<name>"),
    Entry("GEN820", (_E,), "rclpy backend cannot express an affordance", "--partial skips it"),
    Entry("GEN821", (_W,), "rclpy backend skipped an affordance (--partial)"),
    Entry("GEN822", (_E,), "rclpy backend: generated method names clash", "rename one of the affordances"),
    Entry("GEN840", (_E,), "rospy backend cannot express a message field"),
    Entry("GEN841", (_E,), "rospy backend: generated method names clash", "rename one of the affordances"),
    Entry(
        "GEN842",
        (_E,),
        "rospy backend: a type ROS 1 cannot use (not found, or for ROS 2 only: the message says why)",
        "add definitions ROS 1 can build with --interfaces, or use the rclpy backend",
    ),
    Entry(
        "GEN860",
        (_E,),
        "events backend option is not valid (events.robots: the robot ids the broker ACL is written for)",
        "robot ids are 1-128 letters, digits, '_', '.', '-'",
    ),
    # -- SCF1: scaffolding a TD from a robot ------------------------------------------------------------
    Entry("SCF100", (_E,), "scaffold source cannot be read (bag or listing missing, unreadable or malformed)"),
    Entry("SCF101", (_E,), "the ROS graph cannot be read (no rclpy, no ROS 1 master at the URI)"),
    Entry("SCF102", (_E,), "nothing to scaffold: no topic, service or action left after the filters"),
    Entry(
        "SCF103",
        (_W,),
        "interface type not known: the affordance is written without a data schema",
        "give the folder of its interface package with --interfaces",
    ),
    Entry("SCF104", (_W,), "robot namespaces of a fleet differ: the Thing Model has only what they share"),
    Entry("SCF105", (_I,), "robot namespace(s) written as {{robotName}}"),
    Entry("SCF106", (_W,), "a ROS name has several types: the first one is used"),
    Entry("SCF107", (_W,), "a ROS 1 service's type could not be read from its server: the service is left out"),
    Entry("SCF108", (_E,), "invalid regular expression in --include/--exclude"),
    Entry("SCF109", (_W,), "--merge: an affordance of the existing TD is not in the source; it is kept as it is"),
    Entry("SCF110", (_E,), "--merge: the existing TD cannot be read or is not a TD"),
    Entry("SCF111", (_E,), "scaffold listing: an entry is not a name with a type"),
    Entry(
        "SCF112",
        (_E,),
        "--robot-namespace of several segments: {{robotName}} stands for one name segment",
        "give one segment (e.g. rb1_base_a): robotName is also the robot id and its MQTT topic root",
    ),
    Entry("SCF113", (_I,), "--merge: hand-written data schema constraints the ROS types allow are kept (listed)"),
    Entry(
        "SCF114",
        (_W,),
        "--merge: a hand-written data schema constraint the ROS type contradicts is dropped",
        "a bound looser than the type's own, one that leaves no value, or one for another JSON type",
    ),
    Entry(
        "SCF115",
        (_I,),
        "td2adaptor's own ROS nodes (an edge node, the scaffold's reader) are left out: they are not the robot",
        "--node NAME keeps one",
    ),
    # -- CFG9: project configuration ---------------------------------------------------------------------
    Entry("CFG900", (_E,), "configuration file cannot be read"),
    Entry("CFG901", (_E,), "configuration file is not valid TOML"),
    Entry("CFG902", (_E,), "[tool.td2adaptor] is not a table"),
    Entry("CFG903", (_E,), "no [[tool.td2adaptor.target]] tables: nothing to generate"),
    Entry("CFG904", (_E,), "configuration value has the wrong type"),
    Entry("CFG905", (_E,), "unknown key in a target table"),
    Entry("CFG906", (_E,), "a target's tds pattern matches no file"),
    Entry("CFG907", (_E,), "no TD given and no configuration file found", "give a TD or add a td2adaptor.toml"),
)

_BY_CODE: dict[str, Entry] = {e.code: e for e in _ENTRIES}
_STAGES: list[Stage] = list(STAGES)  # the pipeline's stages, then each registered backend's, in that order

#: code → entry of every code known in this process: the pipeline's, and those of every backend registered
CATALOGUE: Mapping[str, Entry] = MappingProxyType(_BY_CODE)


def register(stage: Stage, entries: tuple[Entry, ...]) -> Stage:
    """Add a backend's own stage and codes (once per process; again with the same ones is a no-op).

    ValueError (a bug of the backend, never bad input) for a stage without a backend or without codes, a
    prefix another stage's codes would share, or a code outside the prefix or already known.
    """
    if any(s == stage for s in _STAGES):
        if any(_BY_CODE.get(e.code) != e for e in entries):
            raise ValueError(f"stage {stage.prefix} is already registered with other codes")
        return stage
    problem = _stage_problem(stage, entries)
    if problem:
        raise ValueError(f"cannot register diagnostic stage {stage.prefix!r}: {problem}")
    _STAGES.append(stage)
    _BY_CODE.update((e.code, e) for e in entries)
    return stage


def _stage_problem(stage: Stage, entries: tuple[Entry, ...]) -> str | None:
    if not stage.backend:
        return "a registered stage names its backend"
    if not entries:
        return "it has no codes"
    for other in _STAGES:
        if other.prefix.startswith(stage.prefix) or stage.prefix.startswith(other.prefix):
            return f"its prefix overlaps {other.prefix!r} ({other.title})"
    for entry in entries:
        if not entry.code.startswith(stage.prefix):
            return f"{entry.code} does not start with the prefix"
        if entry.code in _BY_CODE:
            return f"{entry.code} is already known"
    if len({e.code for e in entries}) != len(entries):
        return "a code is listed twice"
    return None


def stages() -> tuple[Stage, ...]:
    """Every stage known in this process: the pipeline's (`STAGES`), then the registered backends'."""
    return tuple(_STAGES)


def stage_of(code: str) -> Stage:
    """The stage a code belongs to: the longest matching prefix (`TD25` before a hypothetical `TD2`)."""
    matches = [s for s in _STAGES if code.startswith(s.prefix)]
    if not matches:
        raise KeyError(f"no stage for diagnostic code {code!r}")
    return max(matches, key=lambda s: len(s.prefix))


def lookup(code: str) -> Entry:
    """The entry of `code`; KeyError (naming the catalogue) if it has none."""
    try:
        return CATALOGUE[code.upper()]
    except KeyError:
        raise KeyError(f"diagnostic code {code!r} is not in td2adaptor.diagnostics.catalogue") from None


def meaning(code: str) -> str:
    """The one-line meaning of `code` (also the message text of codes that need no more)."""
    return lookup(code).meaning


def meanings(prefix: str) -> dict[str, str]:
    """Code → meaning of every code starting with `prefix`, for modules that list the codes they report."""
    return {code: e.meaning for code, e in CATALOGUE.items() if code.startswith(prefix)}


def by_stage(chosen: tuple[Stage, ...] | None = None) -> list[tuple[Stage, list[Entry]]]:
    """The entries grouped by stage (every known stage, or the `chosen` ones), in pipeline order then the
    backends' in registration order; codes in each group in code order."""
    wanted = [s for s in _STAGES if chosen is None or s in chosen]
    return [(s, sorted((e for e in _BY_CODE.values() if stage_of(e.code) is s), key=lambda e: e.code)) for s in wanted]

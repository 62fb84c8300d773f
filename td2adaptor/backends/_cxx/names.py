"""C/C++ names and text for generated code: the C types of ROS primitives, the words C++ reserves, the macros
the C library and GCC may define, comments that stay comments, and deterministic mangling of unusable names.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Iterable

from td2adaptor.generation import textsafe as ts

#: ROS 1 primitive → (C/C++ type, wire size). `bool` is uint8_t on the wire and in memory (as gencpp does).
PRIMITIVES: dict[str, tuple[str, int]] = {
    "bool": ("uint8_t", 1),
    "byte": ("int8_t", 1),
    "char": ("uint8_t", 1),
    "int8": ("int8_t", 1),
    "uint8": ("uint8_t", 1),
    "int16": ("int16_t", 2),
    "uint16": ("uint16_t", 2),
    "int32": ("int32_t", 4),
    "uint32": ("uint32_t", 4),
    "int64": ("int64_t", 8),
    "uint64": ("uint64_t", 8),
    "float32": ("float", 4),
    "float64": ("double", 8),
}

#: C++ keywords and alternative tokens (C++98 to C++20, so code stays valid for newer compilers too).
CPP_KEYWORDS = frozenset(
    """alignas alignof and and_eq asm auto bitand bitor bool break case catch char char8_t char16_t char32_t
    class compl concept const consteval constexpr constinit const_cast continue co_await co_return co_yield
    decltype default delete do double dynamic_cast else enum explicit export extern false float for friend
    goto if inline int long mutable namespace new noexcept not not_eq nullptr operator or or_eq private
    protected public register reinterpret_cast requires return short signed sizeof static static_assert
    static_cast struct switch template this thread_local throw true try typedef typeid typename union
    unsigned using virtual void volatile wchar_t while xor xor_eq""".split()
)
#: Macros that the C library or GCC (GNU modes) may define and that would silently replace a name.
C_MACROS = frozenset(
    """linux unix i386 major minor makedev errno stdin stdout stderr assert offsetof setjmp va_arg va_start
    va_end NULL EOF TRUE FALSE BUFSIZ FILENAME_MAX FOPEN_MAX L_tmpnam TMP_MAX SEEK_SET SEEK_CUR SEEK_END
    CHAR_BIT SCHAR_MIN SCHAR_MAX UCHAR_MAX CHAR_MIN CHAR_MAX MB_LEN_MAX SHRT_MIN SHRT_MAX USHRT_MAX INT_MIN
    INT_MAX UINT_MAX LONG_MIN LONG_MAX ULONG_MAX LLONG_MIN LLONG_MAX ULLONG_MAX SIZE_MAX PTRDIFF_MIN
    PTRDIFF_MAX WCHAR_MIN WCHAR_MAX WINT_MIN WINT_MAX SIG_ATOMIC_MIN SIG_ATOMIC_MAX HUGE_VAL HUGE_VALF
    HUGE_VALL INFINITY NAN FP_NAN FP_INFINITE FP_ZERO FP_NORMAL FP_SUBNORMAL EDOM ERANGE EILSEQ EINVAL
    ENOMEM EAGAIN EBUSY EEXIST ENOENT EIO EPERM EINTR ENOSPC ETIMEDOUT RAND_MAX EXIT_SUCCESS EXIT_FAILURE
    CLOCKS_PER_SEC""".split()
)
#: Families of such macros (stdint, math.h, float.h) and the names C and C++ reserve (`_X...`).
C_MACRO_PATTERN = re.compile(
    r"(?:U?INT(?:8|16|32|64|MAX|PTR|_LEAST(?:8|16|32|64)|_FAST(?:8|16|32|64))_(?:MIN|MAX)"
    r"|U?INT(?:8|16|32|64|MAX)_C|M_[A-Z0-9_]+|(?:FLT|DBL|LDBL)_[A-Z0-9_]+|_[A-Z_][A-Za-z0-9_]*)"
)


def c_macro_like(name: str) -> bool:
    """Whether `name` may be a macro of the C library or the compiler (or is reserved in C and C++)."""
    return name in C_MACROS or C_MACRO_PATTERN.fullmatch(name) is not None


def comment(text: str) -> str:
    """TD or definition text for inside a C/C++ comment: `c_comment`, then no comment delimiter or trigraph
    may re-form (`c_comment` turns `\\` into `/`, so `*\\` would otherwise become `*/`)."""
    out = ts.c_comment(text)
    while True:
        fixed = out.replace("*/", "* /").replace("/*", "/ *").replace("??", "? ?")
        if fixed == out:
            return out
        out = fixed


def mangle(name: str, reserved: Iterable[str], taken: set[str], macro_like: Callable[[str], bool]) -> str:
    """`name`, or the first of `name_`, `name_m`, `name_m2`, ... that is neither reserved, macro-like nor taken
    (macro patterns are upper case, so a lower-case suffix always gets out of them)."""
    reserved_set = set(reserved)
    candidates = [name, name + "_", name + "_m"]
    n = 2
    while True:
        for out in candidates:
            if out not in reserved_set and out not in taken and not macro_like(out):
                return out
        candidates = [f"{name}_m{n}"]
        n += 1

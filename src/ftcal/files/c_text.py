"""Text that goes into generated C and C++: comments, string literals and identifiers.

Every string that reaches generated C comes from a file ftcal does not trust
(a model or payload file: names, units, frames, descriptions) or from the
command line (``--name``). This module is the one place that turns such text
into C, so that no file can smuggle code into a controller's build:

* :func:`c_comment_text` keeps printable ASCII only and spells everything else
  ``<U+XXXX>``, so no newline, control, bidirectional-override (``U+202E``,
  "Trojan Source") or other invisible character reaches the file; the
  backslash is spelled too (a comment line ending in ``\\`` would splice the
  next line into the comment); ``*/`` and ``/*`` are split, and so is every
  ``??`` (a trigraph such as ``??/`` is a backslash under ``-std=c99``).
* :func:`c_string` writes a string literal whose bytes equal the UTF-8 of the
  text: anything but printable ASCII, and ``"``, ``\\`` and ``?``, as octal
  escapes.
* :func:`c_identifier` accepts only identifiers (the ``--name`` prefix);
  identifiers are never made from file contents.
"""

from __future__ import annotations

import re

from ..runtime.errors import FtcalError, ParameterError

_IDENTIFIER = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
_C_KEYWORDS = frozenset(
    "auto break case char const continue default do double else enum extern float for goto if inline "
    "int long register restrict return short signed sizeof static struct switch typedef union unsigned "
    "void volatile while _Bool _Complex _Imaginary".split())
# C++ keywords too: the header is included from C++ (extern "C").
_CPP_KEYWORDS = frozenset(
    "alignas alignof and and_eq asm bitand bitor bool catch class compl concept consteval constexpr constinit "
    "const_cast co_await co_return co_yield decltype delete dynamic_cast explicit export false friend mutable "
    "namespace new noexcept not not_eq nullptr operator or or_eq private protected public reinterpret_cast "
    "requires static_assert static_cast template this thread_local throw true try typeid typename using "
    "virtual wchar_t xor xor_eq char8_t char16_t char32_t".split())
MAX_IDENTIFIER = 63
"""Longest ``--name``: C99 guarantees 63 significant characters in an internal identifier."""


def described(names, units, sep: str = ", ") -> str:
    """``"Fx [N], T"``: each name with its unit in brackets when it has one (generated code and ONNX metadata)."""
    units = units or (None,) * len(names)
    return sep.join(n if u is None else f"{n} [{u}]" for n, u in zip(names, units))


def printable_ascii(text: str) -> str:
    """``text`` with every character outside printable ASCII (and the backslash) spelled ``<U+XXXX>``."""
    return "".join(ch if " " <= ch <= "~" and ch != "\\" else f"<U+{ord(ch):04X}>" for ch in str(text))


def c_comment_text(text: str) -> str:
    """``text`` made safe inside a ``/* ... */`` comment, on one line.

    Parameters
    ----------
    text : any string (a name, unit, file name or description from a file)

    Returns
    -------
    str
        Printable ASCII without a backslash, ``*/``, ``/*`` or ``??``: it can
        neither end the comment, open a nested one (``-Wcomment``), continue
        onto the next line, nor form a trigraph.
    """
    safe = printable_ascii(text)
    safe = re.sub(r"\*(?=/)", "* ", safe)
    safe = re.sub(r"/(?=\*)", "/ ", safe)
    return re.sub(r"\?(?=\?)", "? ", safe)


def c_comment(lines) -> str:
    """A block comment holding ``lines`` (each passed through :func:`c_comment_text`)."""
    return "/*\n" + "".join(f" * {c_comment_text(line)}\n" for line in lines) + " */"


def c_string(text: str) -> str:
    """A C string literal whose bytes are the UTF-8 encoding of ``text``.

    Printable ASCII other than ``"``, ``\\`` and ``?`` (trigraphs) is written
    as itself; every other byte as a three-digit octal escape (which never
    swallows a following digit). Lone surrogates, which have no UTF-8, are
    written as their surrogate-escaped bytes rather than failing.
    """
    out = []
    for ch in str(text):
        if " " <= ch <= "~" and ch not in '"\\?':
            out.append(ch)
        else:
            out.append("".join(f"\\{b:03o}" for b in ch.encode("utf-8", "surrogatepass")))
    return '"' + "".join(out) + '"'


def c_identifier(name: str, parameter: str = "name") -> str:
    """``name`` if it can prefix C identifiers, macros and file names; :class:`FtcalError` otherwise.

    Raises
    ------
    FtcalError
        Not ``[A-Za-z_][A-Za-z0-9_]*``, longer than :data:`MAX_IDENTIFIER`, a C or
        C++ keyword, or reserved (``__`` prefix, ``_`` + capital).
    """
    if (not isinstance(name, str) or not _IDENTIFIER.fullmatch(name) or len(name) > MAX_IDENTIFIER
            or name in _C_KEYWORDS or name in _CPP_KEYWORDS or name.startswith("__")
            or re.match(r"_[A-Z]", name)):
        raise ParameterError(parameter, f"{{{parameter}}} {printable_ascii(repr(name))[:80]} is not a C identifier (1 to {MAX_IDENTIFIER} "
                         "letters, digits and underscores, not starting with a digit, not a C or C++ keyword, "
                         "not starting with '__' or '_' and a capital).")
    return name

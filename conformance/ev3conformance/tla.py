"""TLA+ values as TLC prints them, parsed into Python, and Python values written as TLA+ literals.

Records -> dict, sequences/tuples -> tuple, sets -> frozenset, strings -> str, integers -> int,
TRUE/FALSE -> bool. Functions printed as (k :> v @@ ...) -> dict.
"""

from __future__ import annotations

import re

_TOKEN = re.compile(r'\s*(<<|>>|\|->|:>|@@|"(?:[^"\\]|\\.)*"|-?\d+|[A-Za-z_][A-Za-z_0-9]*|[\[\]{}(),])',
                    re.S)


class TlaParseError(ValueError):
    pass


class Rec(dict):
    """A TLA+ record / function: a dict that can be a set element (sets of records, MCMaster)."""

    def __hash__(self) -> int:  # type: ignore[override]
        return hash(tuple(sorted((repr(k), v) for k, v in self.items())))


def _tokens(text: str) -> list[str]:
    out, i, n = [], 0, len(text)
    while i < n:
        m = _TOKEN.match(text, i)
        if not m:
            if text[i:].strip() == "":
                break
            raise TlaParseError(f"cannot read TLA+ value at {text[i:i + 40]!r}")
        out.append(m.group(1))
        i = m.end()
    return out


def _unquote(tok: str) -> str:
    body = tok[1:-1]
    return re.sub(r'\\(.)', lambda m: {"n": "\n", "t": "\t"}.get(m.group(1), m.group(1)), body)


class ModelValue(str):
    """A TLC model value (a bare name such as a1 in `Agents = {a1, a2}`), read with model_values=True."""

    def __repr__(self) -> str:
        return str(self)


class _Parser:
    def __init__(self, toks: list[str], model_values: bool = False) -> None:
        self.t = toks
        self.i = 0
        self.model_values = model_values

    def peek(self) -> str | None:
        return self.t[self.i] if self.i < len(self.t) else None

    def take(self, want: str | None = None) -> str:
        tok = self.peek()
        if tok is None or (want is not None and tok != want):
            raise TlaParseError(f"expected {want or 'a value'}, found {tok!r}")
        self.i += 1
        return tok

    def value(self):
        tok = self.take()
        if tok == "<<":
            items = []
            if self.peek() != ">>":
                items.append(self.value())
                while self.peek() == ",":
                    self.take(",")
                    items.append(self.value())
            self.take(">>")
            return tuple(items)
        if tok == "[":
            rec = Rec()
            if self.peek() != "]":
                while True:
                    key = self.take()
                    self.take("|->")
                    rec[key] = self.value()
                    if self.peek() == ",":
                        self.take(",")
                        continue
                    break
            self.take("]")
            return rec
        if tok == "{":
            items = []
            if self.peek() != "}":
                items.append(self.value())
                while self.peek() == ",":
                    self.take(",")
                    items.append(self.value())
            self.take("}")
            return frozenset(items)
        if tok == "(":
            fn = Rec()
            while True:
                k = self.value()
                self.take(":>")
                fn[k] = self.value()
                if self.peek() == "@@":
                    self.take("@@")
                    continue
                break
            self.take(")")
            return fn
        if tok.startswith('"'):
            return _unquote(tok)
        if tok == "TRUE":
            return True
        if tok == "FALSE":
            return False
        if re.fullmatch(r"-?\d+", tok):
            return int(tok)
        if self.model_values and re.fullmatch(r"[A-Za-z_][A-Za-z_0-9]*", tok):
            return ModelValue(tok)
        raise TlaParseError(f"unexpected {tok!r}")


def parse_value(text: str, model_values: bool = False):
    """model_values: a bare name is a ModelValue (TLC prints model values unquoted); else an error."""
    p = _Parser(_tokens(text), model_values)
    v = p.value()
    if p.peek() is not None:
        raise TlaParseError(f"trailing {p.peek()!r}")
    return v


_ASSIGN = re.compile(r"^/\\ (\w+) = ", re.M)


def parse_state(text: str, model_values: bool = False) -> dict:
    """A TLC state printout ("/\\ x = ...\\n/\\ y = ...") -> {x: value, y: value}."""
    marks = list(_ASSIGN.finditer(text))
    if not marks:
        # A state of one variable is printed without the conjunction.
        m = re.match(r"\s*(\w+) = (.*)$", text, re.S)
        if not m:
            raise TlaParseError(f"not a state: {text[:80]!r}")
        return {m.group(1): parse_value(m.group(2), model_values)}
    out = {}
    for k, m in enumerate(marks):
        end = marks[k + 1].start() if k + 1 < len(marks) else len(text)
        out[m.group(1)] = parse_value(text[m.end():end], model_values)
    return out


def to_tla(v) -> str:
    """A Python value as a TLA+ literal (dict -> record; list/tuple -> sequence)."""
    if isinstance(v, bool):
        return "TRUE" if v else "FALSE"
    if isinstance(v, int):
        # TLC's integers are 32-bit signed. A msgid is 32-bit unsigned: an ev3-master without a
        # state file starts from the wall clock (ev3proto/msgids.hpp), at 2^31 or above half the
        # time. Written modulo 2^31: equal stays equal, and the order holds within a run whose
        # msgids do not cross a multiple of 2^31 (docs/spec.md "Implementation -> spec").
        return str(v % (1 << 31)) if v >= 1 << 31 else str(v)
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n") + '"'
    if isinstance(v, dict):
        if not v:
            return "<<>>"  # an empty record does not exist in TLA+; callers avoid it
        return "[" + ", ".join(f"{k} |-> {to_tla(x)}" for k, x in v.items()) + "]"
    if isinstance(v, (list, tuple)):
        return "<<" + ", ".join(to_tla(x) for x in v) + ">>"
    if isinstance(v, (set, frozenset)):
        return "{" + ", ".join(sorted(to_tla(x) for x in v)) + "}"
    raise TypeError(f"no TLA+ literal for {type(v).__name__}")


def show(v) -> str:
    """Compact readable form (for reports)."""
    if isinstance(v, dict):
        return "[" + ", ".join(f"{k}: {show(x)}" for k, x in v.items()) + "]"
    if isinstance(v, tuple):
        return "<<" + ", ".join(show(x) for x in v) + ">>"
    if isinstance(v, str):
        return '"' + v + '"'
    return repr(v) if not isinstance(v, bool) else ("TRUE" if v else "FALSE")

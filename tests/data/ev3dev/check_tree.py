#!/usr/bin/env python3
"""Check an ev3dev sysfs tree against a reference tree (tests/data/ev3dev/<generation>).

    check_tree.py [--overlay DIR]... [--live] [--allow-extra] [--exact] REFERENCE CANDIDATE
    check_tree.py --materialize [--overlay DIR]... REFERENCE DEST

REFERENCE is a reference tree (e.g. tests/data/ev3dev/stretch); its manifest REFERENCE.manifest
gives each entry's kind, sysfs mode and content rule (git keeps no file modes, so modes come from
the manifest, never from the reference's files). CANDIDATE is a copy of it, the simulator's FUSE
mount, or a brick's /sys (then with --allow-extra). Every difference is printed, one a line:

    missing: PATH          an entry of the reference is not in the candidate
    extra: PATH            the candidate has an entry the reference does not (not with --allow-extra)
    kind: PATH ...         file / directory / symlink mismatch
    mode: PATH ...         permission bits differ from the manifest (with --live: from a brick's,
                           EV3DEV_GROUP_CLASSES' attribute files group-writable as the owner)
    symlink: PATH ...      the link points somewhere else
    content: PATH ...      the content breaks its rule (see RULES)
    device: ...            no device with the reference's address and driver in a class directory

Exit status 0 if there is no difference, 1 if there is any, 2 on bad usage.

Devices of the renumbered classes (tacho-motor, lego-sensor) are matched by address and
driver_name, not by their motorN/sensorN name: a candidate that names the left motor motor3 is
fine. Dynamic values (position, speed, valueN, voltage_now, state, ...) are judged by format only;
--exact also demands the reference's boot-time contents. Attributes whose read fails on a brick
(a sensor's value1 in a one-value mode: ENXIO; poll_ms: EOPNOTSUPP) are empty files in a plain
copy; with --live (a FUSE mount or a brick) the read must fail with that errno instead.
--overlay DIR adds a device subtree (e.g. overlays/gyro-in2/stretch) to the reference.
--materialize copies REFERENCE (and overlays) to DEST with the manifest's modes applied.
Standard library only.
"""

from __future__ import annotations

import argparse
import errno
import json
import os
import re
import shutil
import stat
import sys
from dataclasses import dataclass
from pathlib import Path

HERE = Path(__file__).resolve().parent
RENUMBERED = ("tacho-motor", "lego-sensor")
# The classes whose devices' attribute files ev3dev's udev rules give to group ev3dev, copying the
# owner's permission bits to the group's (g=u): the manifests hold the kernel's modes, a brick and
# ev3-sim (--live) show these.
EV3DEV_GROUP_CLASSES = ("tacho-motor", "lego-sensor", "leds", "lego-port")


def brick_mode(path: str, mode: int) -> int:
    """The mode of attribute file @path on a brick: g=u inside a device of EV3DEV_GROUP_CLASSES."""
    parts = path.split("/")
    if any(parts[i] in EV3DEV_GROUP_CLASSES and parts[0] == "devices" for i in range(len(parts) - 2)):
        return (mode & ~0o070) | ((mode & 0o700) >> 3)
    return mode

RULES = """\
exact           the reference's bytes
int / uint      a decimal integer and a newline (uint: not negative)
word            one word and a newline
oneof:A,B       one of the listed words and a newline
flags:A,B       zero or more of the listed words, space-separated, and a newline
member:SIB      one of the words listed by sibling attribute SIB (stop_action in stop_actions)
modefield:F     the driver's value of F for the current mode (drivers.json)
value:N         valueN: an integer while N < num_values, otherwise the read fails with ENXIO
err:ERRNO       the read fails with ERRNO (--live); empty in a plain copy
writeonly       mode 0200; never read
binary:N        N bytes
trigger         trigger list: words, exactly one [selected], including none and timer
brightness      an integer from 0 to max_brightness
kv:K1,K2        KEY=VALUE lines with the reference's keys in order; K1, K2 are integers (a
                key ending in SERIAL_NUM: 12 hex digits), the other values equal the reference's
"""


@dataclass
class Entry:
    kind: str      # d, f, l, c (conditional file)
    mode: int
    rule: str
    target: str    # symlink target ("" otherwise)
    source: Path   # the reference tree root holding this entry's content
    path: str      # its path in that tree


def load_manifest(root: Path) -> dict[str, Entry]:
    manifest = root.parent / f"{root.name}.manifest"
    if not manifest.is_file():
        raise SystemExit(f"check_tree.py: no manifest {manifest} for reference {root}")
    entries = {}
    for number, line in enumerate(manifest.read_text().splitlines(), 1):
        if not line or line.startswith("#"):
            continue
        fields = line.split("\t")
        if len(fields) != 5 or fields[1] not in ("d", "f", "l", "c"):
            raise SystemExit(f"check_tree.py: {manifest}:{number}: malformed line")
        path, kind, mode, rule, target = fields
        entries[path] = Entry(kind, int(mode, 8), rule, target, root, path)
    return entries


def load_reference(reference: Path, overlays: list[Path]) -> dict[str, Entry]:
    entries = load_manifest(reference)
    for overlay in overlays:
        for path, entry in load_manifest(overlay).items():
            if path in entries and entries[path].kind != "d":
                raise SystemExit(f"check_tree.py: overlay {overlay} redefines {path}")
            entries.setdefault(path, entry)
    return entries


def materialize(entries: dict[str, Entry], dest: Path) -> None:
    """Copy the reference entries to dest: sysfs modes applied, conditional files left out."""
    dest.mkdir(parents=True, exist_ok=True)
    for path in sorted(entries):
        entry, out = entries[path], dest / path
        if entry.kind == "d":
            out.mkdir(exist_ok=True)
        elif entry.kind == "f":
            shutil.copyfile(entry.source / path, out)
        elif entry.kind == "l":
            os.symlink(entry.target, out)
    for path in sorted(entries, reverse=True):  # children before parents
        entry = entries[path]
        if entry.kind in ("d", "f"):
            os.chmod(dest / path, entry.mode)


class Missing(Exception):
    """A sibling attribute a rule depends on does not exist."""


def read(path: Path) -> tuple[bytes | None, int | None]:
    try:
        with open(path, "rb") as f:
            return f.read(), None
    except OSError as e:
        return None, e.errno


class Checker:
    def __init__(self, entries: dict[str, Entry], candidate: Path, live: bool, exact: bool,
                 allow_extra: bool) -> None:
        self.entries = entries
        self.cand = candidate
        self.live = live
        self.exact = exact
        self.allow_extra = allow_extra
        self.drivers = json.loads((HERE / "drivers.json").read_text())
        self.problems: list[str] = []
        self.rename: dict[tuple[str, str], str] = {}
        self.skipped: list[str] = []  # reference device dirs with no counterpart

    def problem(self, text: str) -> None:
        self.problems.append(text)

    # --- devices matched by address and driver name ------------------------------------------

    @staticmethod
    def _identity(device_dir: Path) -> tuple[str, str] | None:
        address, _ = read(device_dir / "address")
        driver, _ = read(device_dir / "driver_name")
        if address is None or driver is None:
            return None
        return address.decode(errors="replace").strip(), driver.decode(errors="replace").strip()

    def match_devices(self) -> None:
        for path, entry in self.entries.items():
            parts = path.split("/")
            if entry.kind != "l" or len(parts) != 3 or parts[0] != "class":
                continue
            cls, name = parts[1], parts[2]
            if cls not in RENUMBERED:
                continue
            ref_dir = os.path.normpath(os.path.join(f"class/{cls}", entry.target))
            ident = self._identity(entry.source / ref_dir)
            found = None
            class_dir = self.cand / "class" / cls
            if class_dir.is_dir():
                for cand_name in sorted(os.listdir(class_dir)):
                    if self._identity(class_dir / cand_name) == ident:
                        found = cand_name
                        break
            if found is None and os.path.lexists(class_dir / name):
                continue  # the reference's name is there: its symlink and files get checked
            if found is None:
                self.problem(f"device: no {cls} device with driver_name {ident[1]} and address "
                             f"{ident[0]} (the reference's class/{cls}/{name})")
                self.skipped.extend([path, ref_dir])
            elif found != name:
                self.rename[(cls, name)] = found

    def translate(self, path: str) -> str:
        if not self.rename:
            return path
        parts = path.split("/")
        for i in range(1, len(parts)):
            parts[i] = self.rename.get((parts[i - 1], parts[i]), parts[i])
        return "/".join(parts)

    def is_skipped(self, path: str) -> bool:
        return any(path == s or path.startswith(s + "/") for s in self.skipped)

    # --- the walk --------------------------------------------------------------------------

    def run(self) -> list[str]:
        if not self.cand.is_dir():
            self.problem(f"missing: {self.cand} is not a directory")
            return self.problems
        self.match_devices()
        expected: dict[str, Entry] = {}
        for path, entry in self.entries.items():
            if self.is_skipped(path):
                continue
            if entry.kind == "c" and not self.condition_holds(path):
                continue
            expected[self.translate(path)] = entry
        for cpath in sorted(expected):
            self.check_entry(cpath, expected[cpath])
        if not self.allow_extra:
            self.find_extra(set(expected))
        return self.problems

    def condition_holds(self, path: str) -> bool:
        """delay_on / delay_off exist while the LED's trigger is timer."""
        trigger, _ = read(self.cand / self.translate(os.path.dirname(path)) / "trigger")
        return trigger is not None and b"[timer]" in trigger.split()

    def check_entry(self, cpath: str, entry: Entry) -> None:
        full = self.cand / cpath
        try:
            st = os.lstat(full)
        except FileNotFoundError:
            why = " (the trigger is timer)" if entry.kind == "c" else ""
            self.problem(f"missing: {cpath}{why}")
            return
        except OSError as e:
            self.problem(f"missing: {cpath} ({os.strerror(e.errno)})")
            return
        kind = "l" if stat.S_ISLNK(st.st_mode) else "d" if stat.S_ISDIR(st.st_mode) else \
            "f" if stat.S_ISREG(st.st_mode) else "?"
        want = "f" if entry.kind == "c" else entry.kind
        names = {"d": "a directory", "f": "a file", "l": "a symlink", "?": "something else"}
        if kind != want:
            self.problem(f"kind: {cpath} is {names[kind]}, expected {names[want]}")
            return
        if kind == "l":
            target, expected = os.readlink(full), self.translate(entry.target)
            if target != expected:
                self.problem(f"symlink: {cpath} -> {target}, expected -> {expected}")
            return
        mode = stat.S_IMODE(st.st_mode)
        want_mode = brick_mode(cpath, entry.mode) if self.live and kind == "f" else entry.mode
        if mode != want_mode:
            self.problem(f"mode: {cpath} is {mode:04o}, expected {want_mode:04o}")
        if kind == "f":
            self.check_content(cpath, entry)

    def find_extra(self, expected: set[str]) -> None:
        for dirpath, dirnames, filenames in os.walk(self.cand):
            rel_dir = os.path.relpath(dirpath, self.cand)
            keep = []
            for name in sorted(dirnames):
                rel = name if rel_dir == "." else f"{rel_dir}/{name}"
                if rel in expected:
                    keep.append(name)
                else:
                    self.problem(f"extra: {rel}")
            dirnames[:] = keep
            for name in sorted(filenames):
                rel = name if rel_dir == "." else f"{rel_dir}/{name}"
                if rel not in expected:
                    self.problem(f"extra: {rel}")

    # --- content rules ---------------------------------------------------------------------

    def sibling(self, cpath: str, name: str) -> str | None:
        """A sibling attribute's text; None if unreadable. A missing sibling raises Missing:
        it is reported as missing itself, so the attribute that depends on it is not judged."""
        data, err = read(self.cand / os.path.dirname(cpath) / name)
        if err == errno.ENOENT:
            raise Missing(name)
        return None if data is None else data.decode(errors="replace")

    @staticmethod
    def reference_bytes(cpath: str, entry: Entry) -> bytes | None:
        return (entry.source / entry.path).read_bytes() if entry.kind == "f" else None

    def check_content(self, cpath: str, entry: Entry) -> None:
        rule, _, arg = entry.rule.partition(":")
        if rule == "writeonly":
            if not self.live:
                data, _ = read(self.cand / cpath)
                if data:
                    self.problem(f"content: {cpath} is a write-only attribute; its copy must be "
                                 f"empty")
            return
        if rule == "value":
            try:
                nv_text = self.sibling(cpath, "num_values")
            except Missing:
                return
            if nv_text is None or not re.fullmatch(r"\d+\n", nv_text):
                self.problem(f"content: {cpath}: cannot judge it, num_values is unreadable")
                return
            if int(arg) < int(nv_text):
                rule = "int"
            else:
                rule, arg = "err", "ENXIO"
        data, err = read(self.cand / cpath)
        if rule == "err":
            code = getattr(errno, arg)
            if self.live:
                if err != code:
                    got = (f"read {data!r}" if data is not None
                           else f"failed with {errno.errorcode.get(err, err)}")
                    self.problem(f"content: {cpath} {got}, expected the read to fail with {arg}")
            elif err is not None or data:
                self.problem(f"content: {cpath} must be an empty placeholder in a plain copy "
                             f"(on a brick its read fails with {arg})")
            return
        if err is not None:
            self.problem(f"content: {cpath} cannot be read ({errno.errorcode.get(err, err)})")
            return
        try:
            reason = self.judge(cpath, entry, rule, arg, data)
        except Missing:
            return
        if reason is None and self.exact and entry.kind == "f":
            ref = self.reference_bytes(cpath, entry)
            if ref is not None and data != ref:
                reason = f"is {data!r}, expected the reference's {ref!r} (--exact)"
        if reason:
            self.problem(f"content: {cpath} {reason}")

    def judge(self, cpath: str, entry: Entry, rule: str, arg: str, data: bytes) -> str | None:
        if rule == "binary":
            return None if len(data) == int(arg) else f"has {len(data)} bytes, expected {arg}"
        try:
            text = data.decode()
        except UnicodeDecodeError:
            return f"is not text: {data!r}"
        shown = repr(text)
        if rule == "exact":
            ref = self.reference_bytes(cpath, entry)
            return None if data == ref else f"is {shown}, expected {ref.decode()!r}"
        if rule == "int":
            return None if re.fullmatch(r"-?\d+\n", text) else f"is {shown}, expected an integer"
        if rule == "uint":
            return None if re.fullmatch(r"\d+\n", text) else \
                f"is {shown}, expected a non-negative integer"
        if rule == "word":
            return None if re.fullmatch(r"\S+\n", text) else f"is {shown}, expected one word"
        if rule == "oneof":
            choices = arg.split(",")
            return None if text[:-1] in choices and text.endswith("\n") else \
                f"is {shown}, expected one of {' '.join(choices)}"
        if rule == "flags":
            allowed = set(arg.split(","))
            if not text.endswith("\n") or (text != "\n" and not re.fullmatch(r"\S+( \S+)*\n", text)):
                return f"is {shown}, expected space-separated flags and a newline"
            bad = [w for w in text.split() if w not in allowed]
            return f"has unknown flags {bad}" if bad else None
        if rule == "member":
            listed = self.sibling(cpath, arg)
            if listed is None:
                return f"cannot be judged: {arg} is unreadable"
            if not re.fullmatch(r"\S+\n", text) or text.strip() not in listed.split():
                return f"is {shown}, expected one of {arg}: {listed.strip()}"
            return None
        if rule == "modefield":
            return self.judge_modefield(cpath, arg, text)
        if rule == "trigger":
            words = text.split()
            selected = [w for w in words if w.startswith("[") and w.endswith("]")]
            names = {w.strip("[]") for w in words}
            if not text.endswith("\n") or len(selected) != 1:
                return f"is {shown}, expected a trigger list with exactly one [selected] trigger"
            if not {"none", "timer"} <= names:
                return "lacks the none or timer trigger"
            return None
        if rule == "brightness":
            top = self.sibling(cpath, "max_brightness")
            if not re.fullmatch(r"\d+\n", text):
                return f"is {shown}, expected an integer"
            if top is None or not re.fullmatch(r"\d+\n", top):
                return "cannot be judged: max_brightness is unreadable"
            return None if int(text) <= int(top) else f"is {text.strip()}, above max_brightness"
        if rule == "kv":
            return self.judge_kv(cpath, entry, arg, text)
        return f"has an unknown rule {entry.rule!r} in the manifest"

    def judge_modefield(self, cpath: str, field: str, text: str) -> str | None:
        driver = (self.sibling(cpath, "driver_name") or "").strip()
        mode = (self.sibling(cpath, "mode") or "").strip()
        modes = self.drivers["lego-sensor"].get(driver, {}).get("modes", [])
        info = next((m for m in modes if m["name"] == mode), None)
        if info is None:
            return f"cannot be judged: mode {mode!r} of driver {driver!r} is not in drivers.json"
        want = f"{info[field]}\n"
        return None if text == want else f"is {text!r}, expected {want!r} in mode {mode}"

    def judge_kv(self, cpath: str, entry: Entry, dynamic: str, text: str) -> str | None:
        ref = self.reference_bytes(cpath, entry).decode().splitlines()
        got = text.splitlines()
        ref_keys = [line.partition("=")[0] for line in ref]
        got_keys = [line.partition("=")[0] for line in got]
        if got_keys != ref_keys or not text.endswith("\n"):
            return f"has keys {got_keys}, expected {ref_keys}"
        for want, have in zip(ref, got):
            key = want.partition("=")[0]
            value = have.partition("=")[2]
            if key in dynamic.split(","):
                pattern = r"[0-9A-F]{12}" if key.endswith("SERIAL_NUM") else r"-?\d+"
                if not re.fullmatch(pattern, value):
                    return f"has {key}={value}, expected an integer"
            elif have != want:
                return f"has {have!r}, expected {want!r}"
        return None


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description="Check an ev3dev sysfs tree against a reference tree.",
        epilog="content rules:\n" + RULES, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("reference", type=Path, help="reference tree, e.g. tests/data/ev3dev/stretch")
    parser.add_argument("candidate", type=Path, help="tree to check (or DEST with --materialize)")
    parser.add_argument("--overlay", type=Path, action="append", default=[],
                        help="add an overlay subtree to the reference (repeatable)")
    parser.add_argument("--live", action="store_true",
                        help="the candidate computes reads (FUSE, brick): demand the read errors")
    parser.add_argument("--allow-extra", action="store_true",
                        help="ignore entries the reference does not have (a brick's full /sys)")
    parser.add_argument("--exact", action="store_true",
                        help="also demand the reference's boot-time contents")
    parser.add_argument("--materialize", action="store_true",
                        help="copy the reference to CANDIDATE with sysfs modes instead of checking")
    args = parser.parse_args(argv)
    reference = args.reference.resolve()
    if not reference.is_dir():
        parser.error(f"reference {args.reference} is not a directory")
    entries = load_reference(reference, [o.resolve() for o in args.overlay])
    if args.materialize:
        if args.candidate.exists() and any(args.candidate.iterdir()):
            parser.error(f"{args.candidate} exists and is not empty")
        materialize(entries, args.candidate)
        return 0
    problems = Checker(entries, args.candidate, args.live, args.exact, args.allow_extra).run()
    for line in problems:
        print(line)
    if problems:
        print(f"check_tree.py: {len(problems)} difference(s) from {args.reference}",
              file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())

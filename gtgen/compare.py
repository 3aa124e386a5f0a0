"""Whether two datasets hold the same data: every file byte for byte, and ``run.mcap``
message by message (topic, log time, payload), so that two runs of one scenario and seed
can be checked to agree across machines, interpreters and versions of this software.

``python -m gtgen.compare A B`` prints one line per difference (at most ``--show``) and a
last line with the counts; exit code 0 when the datasets agree, 1 when they differ, 2 when
a folder is missing. ``manifest.json`` (versions, paths) is not compared; a file that
names its own dataset's folder (``yolo/data.yaml``) is compared with that folder's path
taken out.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Iterator
from dataclasses import dataclass, field
from itertools import zip_longest
from pathlib import Path

from mcap.reader import make_reader

IGNORED = frozenset({"manifest.json"})
MCAP_NAME = "run.mcap"


@dataclass(slots=True)
class Comparison:
    """What was compared and what differed (relative paths, or ``run.mcap#topic@time``)."""

    files: int = 0
    messages: int = 0
    differences: list[str] = field(default_factory=list)

    @property
    def same(self) -> bool:
        return not self.differences


def _files(root: Path) -> set[str]:
    return {str(p.relative_to(root)) for p in root.rglob("*") if p.is_file() and p.name not in IGNORED}


def _messages(path: Path) -> Iterator[tuple[str, int, bytes]]:
    with path.open("rb") as stream:
        for _, channel, message in make_reader(stream).iter_messages(log_time_order=True):
            yield channel.topic, message.log_time, message.data


def compare_mcap(a: Path, b: Path, result: Comparison) -> None:
    for left, right in zip_longest(_messages(a), _messages(b)):
        result.messages += 1
        if left != right:
            where = left or right or ("", 0, b"")
            result.differences.append(f"{a.name}#{where[0]}@{where[1]}")


def compare_datasets(a: Path, b: Path) -> Comparison:
    result = Comparison()
    names_a, names_b = _files(a), _files(b)
    result.differences += [f"{name}: only in {a}" for name in sorted(names_a - names_b)]
    result.differences += [f"{name}: only in {b}" for name in sorted(names_b - names_a)]
    for name in sorted(names_a & names_b):
        result.files += 1
        if name == MCAP_NAME:
            compare_mcap(a / name, b / name, result)
        elif _content(a, name) != _content(b, name):
            result.differences.append(name)
    return result


def _content(root: Path, name: str) -> bytes:
    return (root / name).read_bytes().replace(str(root.resolve()).encode(), b"<dataset>")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m gtgen.compare", description=__doc__.split("\n\n")[0])
    parser.add_argument("a", type=Path)
    parser.add_argument("b", type=Path)
    parser.add_argument("--show", type=int, default=20, help="differences to print (default 20)")
    args = parser.parse_args(argv)
    for folder in (args.a, args.b):
        if not folder.is_dir():
            print(f"error: {folder}: not a dataset folder", file=sys.stderr)
            return 2
    result = compare_datasets(args.a, args.b)
    for line in result.differences[: args.show]:
        print(f"differs: {line}")
    verdict = "same" if result.same else f"{len(result.differences)} differences"
    print(f"{verdict}: {result.files} files, {result.messages} MCAP messages compared")
    return 0 if result.same else 1


if __name__ == "__main__":
    sys.exit(main())

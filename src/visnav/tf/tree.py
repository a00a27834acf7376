"""The TF tree as text or Graphviz dot (what ``view_frames`` / ``tf tree`` show).

Built from :meth:`visnav.tf.Buffer.frame_infos`: each link shows its publisher
(the broadcasting node), its rate and its newest stamp; static links say so.
"""

from __future__ import annotations

from collections.abc import Mapping

from visnav.tf.buffer import FrameInfo

__all__ = ["format_tree", "format_tree_dot", "tree_roots"]


def tree_roots(infos: Mapping[str, FrameInfo]) -> list[str]:
    """Frames that are parents but never children, sorted."""
    parents = {i.parent for i in infos.values()}
    return sorted(p for p in parents if p not in infos)


def _children(infos: Mapping[str, FrameInfo]) -> dict[str, list[str]]:
    kids: dict[str, list[str]] = {}
    for child, info in infos.items():
        kids.setdefault(info.parent, []).append(child)
    for v in kids.values():
        v.sort()
    return kids


def _label(info: FrameInfo) -> str:
    who = info.authority or "unknown publisher"
    if info.is_static:
        return f"static, by {who}"
    newest = info.most_recent_ns / 1e9
    return f"{info.rate_hz:.1f} Hz, newest {newest:.3f} s, by {who}"


def format_tree(infos: Mapping[str, FrameInfo]) -> str:
    """Return an indented text tree, one line per frame with its link's details."""
    if not infos:
        return "(no transforms received)"
    kids = _children(infos)
    lines: list[str] = []

    def walk(frame: str, prefix: str, last: bool, top: bool) -> None:
        if top:
            lines.append(frame)
        else:
            branch = "└── " if last else "├── "
            lines.append(f"{prefix}{branch}{frame}  [{_label(infos[frame])}]")
        children = kids.get(frame, [])
        ext = "" if top else ("    " if last else "│   ")
        for i, child in enumerate(children):
            walk(child, prefix + ext, i == len(children) - 1, top=False)

    roots = tree_roots(infos)
    for root in roots:
        walk(root, "", last=True, top=True)
    visited = {f for line in lines for f in [line.split("── ")[-1].split("  [")[0]]}
    cyclic = sorted(f for f in infos if f not in visited)
    if cyclic:
        lines.append(f"(frames in a loop, unreachable from any root: {', '.join(cyclic)})")
    return "\n".join(lines)


def format_tree_dot(infos: Mapping[str, FrameInfo]) -> str:
    """Return the tree as Graphviz dot (edges parent -> child, labelled)."""
    out = ["digraph tf {"]
    for child, info in sorted(infos.items()):
        label = _label(info).replace('"', "'")
        out.append(f'  "{info.parent}" -> "{child}" [label="{label}"];')
    out.append("}")
    return "\n".join(out)

"""The chosen policies join a seed group (``krl agent heldout --choose ... --seed-group GROUP``).

A seed group is a folder of ``seed<S>/policy.npz`` (with a run folder's small files beside each); more
seeds trained from the choice's ``chosen-config.json`` join it later. Everything is checked before anything
is written (:func:`check_seeded`, :func:`group_copies`), so a refused group leaves no choice behind.
"""

from __future__ import annotations

from pathlib import Path

from krl.util.hashing import file_sha256
from krl.util.output import write_atomic

RUN_FILES: tuple[str, ...] = ("config.json", "run.json", "progress.csv")
"""The small files of a run folder (``krl agent train``'s) that join a seed group beside its policy."""


def check_seeded(label: str, files: list[tuple[int | None, Path]], group: Path) -> None:
    """Raise ``ValueError`` unless every policy of ``label`` has a seed (a seed group holds seeds)."""
    if any(seed is None for seed, _ in files):
        raise ValueError(f"{label!r} is one policy file without a seed: nothing to add to {group}")


def group_copies(label: str, files: list[tuple[int | None, Path]], group: Path) -> list[tuple[Path, Path]]:
    """The ``(target, source)`` copies that put ``label``'s policies into ``group``, each seed's policy
    first; a seed already there with the same policy needs none. Writes nothing.

    Raises:
        ValueError: a policy without a seed, or a seed of ``group`` holding a different policy.
    """
    check_seeded(label, files, group)
    copies: list[tuple[Path, Path]] = []
    for seed, policy in files:
        folder = group / f"seed{seed}"
        if (folder / "policy.npz").exists():
            if file_sha256(folder / "policy.npz") != file_sha256(policy):
                raise ValueError(f"{folder} holds another policy than {policy}: nothing copied to {group}")
            continue
        copies.append((folder / "policy.npz", policy))
        if policy.name == "policy.npz":  # a run folder's
            copies += [(folder / name, policy.parent / name) for name in RUN_FILES]
    return copies


def copy_into_group(copies: list[tuple[Path, Path]]) -> list[str]:
    """Make :func:`group_copies`' copies, each ``policy.npz`` last (a seed folder with one is complete).
    Returns the seed folders written."""
    for target, source in reversed(copies):
        if source.is_file():
            write_atomic(target, source.read_bytes())
    return sorted({str(target.parent) for target, _ in copies})

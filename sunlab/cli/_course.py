"""``sunlab course``: the course's student and teacher editions
(:func:`sunlab.course.write_course`), or students' notebooks graded (:mod:`sunlab.course.grading`).

Examples
--------
>>> from sunlab.cli import build_parser
>>> build_parser().parse_args(["course", "--out", "editions"]).out
'editions'
"""

from __future__ import annotations

import os

from ._args import SECONDS, verb

__all__: list[str] = []


def _add(sub) -> None:
    """Add ``course``."""
    p = verb(sub, "course", run_course, "write the course's student and teacher editions, or "
             "grade students' notebooks (exit 1 when a check fails; docs/teacher-notes.md)",
             overwrite="editions (or a gradebook) written before")
    what = p.add_mutually_exclusive_group(required=True)
    what.add_argument("--out", metavar="DIR", help="write DIR/student and DIR/teacher")
    what.add_argument("--grade", nargs="+", metavar="NOTEBOOK",
                      help="students' notebooks (STUDENT/NN-title.ipynb) to run and grade")
    p.add_argument("--gradebook", metavar="DIR", help="write DIR/gradebook.csv and .json")
    p.add_argument("--seed", type=int, help="seed of the hidden checks (default: drawn)")
    p.add_argument("--notebooks", metavar="DIR", help="the notebooks (default: notebooks/)")
    p.add_argument("--full", action="store_true", help="without the quick-settings cell")
    p.add_argument("--timeout", type=SECONDS, default=180.0,
                   help="with --grade: limit per cell, s (a notebook's budget is 10 limits); "
                   "past it the notebook's open exercises score 0 (default: 180)")


def run_course(args) -> int:
    """``sunlab course``: the editions written, or the notebooks graded (exit 1 when a check
    fails)."""
    if args.grade:
        return _grade(args)
    from ..course import write_course

    res = write_course(args.out, notebooks=args.notebooks, quick=not args.full,
                       overwrite=args.overwrite)
    books = {ex.notebook for ex in res["exercises"]}
    print(f"{len(res['exercises'])} exercises in {len(books)} notebooks, "
          f"{len(res['written'])} written answers; wrote "
          f"{len(res['student'])} student notebooks to {res['student'][0].parent} and "
          f"{len(res['teacher'])} teacher notebooks to {res['teacher'][0].parent}")
    return 0


def _grade(args) -> int:
    """Grade every notebook of ``--grade`` (:func:`sunlab.course.batch.grade_batch`, which
    prints each student's points and each exercise's); the batch's exit status."""
    from pathlib import Path

    from .. import atomic
    from ..course import batch, grading

    if args.gradebook is not None:  # refused before hours of grading, not after
        atomic.check_folder(args.gradebook, grading.GRADEBOOK_FILES, overwrite=args.overwrite,
                            flag="--overwrite")
    seed = args.seed if args.seed is not None else int.from_bytes(os.urandom(3), "big")
    print(f"hidden checks on fresh inputs drawn from seed {seed}")
    _, status = batch.grade_batch(args.grade, notebooks=args.notebooks, seed=seed,
                                  quick=not args.full, timeout=args.timeout,
                                  gradebook=args.gradebook, overwrite=args.overwrite)
    if args.gradebook is not None:
        print(f"wrote {Path(args.gradebook) / 'gradebook.csv'}, "
              f"{Path(args.gradebook) / 'gradebook.json'}")
    return status

"""The course: the notebooks' exercises, their editions, and grading a teacher can trust.

* :mod:`sunlab.course.editions`: exercises and written answers in the numbered notebooks, and
  the student and teacher editions (:func:`write_course`, ``sunlab course --out``);
* :mod:`sunlab.course.grading`: students' notebooks graded against the teacher edition, and
  the gradebook (:func:`grade`, ``sunlab course --grade ... --gradebook DIR``);
* :mod:`sunlab.course.hidden`: each exercise's hidden check on fresh inputs;
* :mod:`sunlab.course.capstone`: the recordings of notebook 08's capstone, rendered by seed.

docs/course.md (the student syllabus) and docs/teacher-notes.md say how to use them.

Examples
--------
>>> src = "# Exercise 01.1: x\\n# Hint: two.\\n### BEGIN SOLUTION\\nx = 2\\n### END SOLUTION\\n"
>>> print(replace_solution(src, "x = None"))
# Exercise 01.1: x
# Hint: two.
x = None
<BLANKLINE>
>>> solution_hint(src)
'two.'
"""

from .editions import (
    BEGIN_HIDDEN,
    BEGIN_SOLUTION,
    END_HIDDEN,
    END_SOLUTION,
    QUICK_CELL,
    WRITTEN_PROMPT,
    Exercise,
    Written,
    default_notebook_dir,
    find_exercises,
    find_written,
    replace_solution,
    solution_hint,
    strip_hidden,
    student_notebook,
    teacher_notebook,
    write_course,
)
from .grading import COLUMNS, grade, grade_notebook, totals, write_gradebook

__all__ = [
    "BEGIN_HIDDEN", "BEGIN_SOLUTION", "COLUMNS", "END_HIDDEN", "END_SOLUTION", "QUICK_CELL",
    "WRITTEN_PROMPT", "Exercise", "Written", "default_notebook_dir", "find_exercises",
    "find_written", "grade", "grade_notebook", "replace_solution", "solution_hint",
    "strip_hidden", "student_notebook", "teacher_notebook", "totals", "write_course",
    "write_gradebook",
]

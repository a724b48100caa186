"""The course: the notebooks' exercises, their editions, and grading a teacher can trust.

* :mod:`sunlab.course.editions`: exercises and written answers in the numbered notebooks, and
  the student and teacher editions (:func:`write_course`, ``sunlab course --out``);
* :mod:`sunlab.course.grading`: students' notebooks graded against the teacher edition, and
  the gradebook (:func:`grade`, ``sunlab course --grade ... --gradebook DIR``);
* :mod:`sunlab.course.hidden`: each exercise's hidden check on fresh inputs;
* :mod:`sunlab.course.kernel`, :mod:`sunlab.course.wire`, :mod:`sunlab.course.probe`: a
  submission's kernel (time limits, process group), the data between it and the grader, and the
  forbidden library calls caught in a fresh process;
* :mod:`sunlab.course.capstone`: the recordings of notebook 08's capstone, rendered by seed.

docs/course.md (the student syllabus) and docs/teacher-notes.md say how to use them.

Examples
--------
>>> from sunlab.course import editions
>>> src = "# Exercise 01.1: x\\n# Hint: two.\\n### BEGIN SOLUTION\\nx = 2\\n### END SOLUTION\\n"
>>> print(editions.replace_solution(src, "x = None"))
# Exercise 01.1: x
# Hint: two.
x = None
<BLANKLINE>
>>> editions.solution_hint(src)
'two.'
"""

import lazy_loader as _lazy

__getattr__, __dir__, __all__ = _lazy.attach_stub(__name__, __file__)

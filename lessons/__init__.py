"""The lessons this distribution ships, one package each (rubric.lesson.Lesson, issue 45): what a lesson owns that
runs inside a case process (its scenes) lives in its package here. Nothing in grader/ or worker/ imports them: the
case process finds a lesson's scenes module by the name its declaration gives."""

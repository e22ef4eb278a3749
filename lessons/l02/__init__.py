"""L02, the simulation lifecycle: one Box followed through declaration, build, stepping and observation, with the
physics held fixed (issue 45: the lesson that proves a lesson is a folder). Its declaration is `lessons.l02.lesson`."""

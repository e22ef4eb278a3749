"""The API's rubric versions routes (grader.services.rubrics): versions, regrade preview and commit."""

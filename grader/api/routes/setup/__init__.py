"""The API's course set-up routes (grader.services.setup): courses, roster, sign-in links, assignments."""

"""L03, falling-cube contact, dt/substeps, friction and stopping distance: its Genesis scenes (`scenes`). Its
declaration, specs, metrics and scoring are still in rubric/ (rubric.l03), and move here in the next steps of issue
45."""

"""Project-level stage functions the pipeline (workbench.pipeline) and the city frames
(workbench.render.city_frame) share: the project's camera geometry, the chart scene, the optical
image, and the cache keys built from what each stage consumes. Nothing here imports the pipeline
or the renderer."""

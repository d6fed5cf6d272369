"""Data sets: jobs over the renderer and the pipeline that make and describe labelled frame sets.

    dataset.py        `workbench dataset`: resumable frame sets (frames, COCO, manifest), their files
    stats.py          `workbench dataset-stats`: objects per frame and class, box heights, distances
    integrity.py      `workbench dataset-verify`: frames and labels checked against the manifest's hashes
    contact_sheet.py  `workbench contact-sheet`: city scene types through the camera, tiled
"""

"""Parameter editors (lens, sensor, ISP): each emits edited(section, {field: value})."""

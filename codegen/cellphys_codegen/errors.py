"""One error type for every descriptor problem, so the build can say file, field and reason."""


class DescriptorError(Exception):
    def __init__(self, path, field, reason):
        self.path = str(path)
        self.field = field
        self.reason = reason
        super().__init__(f"{self.path}: {field}: {reason}")

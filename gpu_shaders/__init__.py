"""GPU side of Lumen GI: the preview RenderEngine and its passes land here.

Nothing is registered yet; register()/unregister() exist so the add-on's entry point already
calls this package and the engine can arrive without touching `__init__.py`.
"""


def register():
    pass


def unregister():
    pass

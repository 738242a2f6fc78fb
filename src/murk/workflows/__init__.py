"""Jobs that orchestrate several layers and the file system (what a command runs end to end): the snow-bank
extraction of ``murk snow extract`` and the demo of ``murk demo``. They sit above report/ and below cli/."""

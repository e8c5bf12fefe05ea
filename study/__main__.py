from study.commands.cli import main

main()
